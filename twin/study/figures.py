"""A study's figures as PNG (:mod:`twin.report.plots`): the paper's Figs. 3–5 and the truth.

- ``fig3_metrics.png``: validation RMSE, MAE (the paper's "STD"), MAX and time per method,
  mean ± std over trials (paper Fig. 3), the axes from zero.
- ``fig4_convergence.png``: validation RMSE per iteration, median over trials with the
  inter-quartile band, per method (paper Fig. 4).
- ``fig5_residuals.png``: cable-length residuals at the validation poses of the first trial,
  before and after each method, and their spread over all trials (paper Fig. 5).
- ``parameter_error.png``: RMS over trials of the part of each method's parameter error the
  data can see (projected off the null space of the cable Jacobian at the truth), per unknown.
- ``sweep.png`` (sweeps only): validation RMSE and flange error against the truth per method
  at each sweep point.

With a sweep, each case's figures carry the case's index: ``fig3_metrics-1.png``…
"""

from __future__ import annotations

from collections.abc import Callable, Generator, Mapping, Sequence
from contextlib import closing
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

import numpy as np

from twin.io.atomic import write_atomic
from twin.io.png import png_bytes
from twin.report.display import LENGTH_DECIMALS, plain
from twin.report.plots import pyplot
from twin.study.progress import Progress

if TYPE_CHECKING:
    from twin.study.executors import Executor

FLOOR = 1e-4
"""Parameter-error plots stop this fraction below their largest value."""


def _colors(methods: Sequence[str]) -> dict[str, Any]:
    cmap = pyplot().get_cmap("tab10")
    return {m: cmap(i % 10) for i, m in enumerate(methods)}


def fig_metrics(table6: Mapping[str, Any], title: str) -> Any:
    """Paper Fig. 3: bars of mean ± std per method for RMSE, "STD", MAX and time."""
    plt = pyplot()
    methods = [m for m in table6 if m != "before"]
    colors = _colors(methods)
    figure, axes = plt.subplots(2, 2, figsize=(11, 7), layout="constrained")
    panels = (("rmse", "(a) RMSE [mm]"), ("mae", '(b) "STD" = MAE [mm]'),
              ("max", "(c) MAX [mm]"), ("seconds", "(d) time per trial [s]"))
    x = np.arange(len(methods))
    for axis, (key, label) in zip(axes.flat, panels, strict=True):
        means = [table6[m][key]["mean"] for m in methods]
        stds = [table6[m][key]["std"] for m in methods]
        axis.bar(x, means, yerr=stds, capsize=3, color=[colors[m] for m in methods])
        # Every metric is at least zero: a std wider than its mean (a skewed time) is cut at
        # the axis, not drawn as a negative time.
        axis.set_ylim(bottom=0.0)
        axis.set_xticks(x, methods, rotation=30, ha="right")
        axis.set_title(label)
        if key != "seconds":
            axis.set_title(f"{label}  (before: "
                           f"{plain(table6['before'][key]['mean'], LENGTH_DECIMALS)})")
        axis.grid(axis="y", alpha=0.3)
    figure.suptitle(title)
    return figure


def fig_convergence(details: Sequence[Mapping[str, Any]], methods: Sequence[str], title: str
                    ) -> Any:
    """Paper Fig. 4: validation RMSE against iteration, median and quartiles over trials."""
    plt = pyplot()
    colors = _colors(methods)
    figure, axis = plt.subplots(figsize=(9, 5.5), layout="constrained")
    for method in methods:
        histories = [d["methods"][method]["history_mm"] for d in details
                     if method in d["methods"]]
        if not histories:
            continue
        length = max(len(h) for h in histories)
        # A method that stopped early stays where it stopped.
        padded = np.array([h + [h[-1]] * (length - len(h)) for h in histories])
        low, median, high = np.percentile(padded, [25, 50, 75], axis=0)
        iterations = np.arange(length)
        axis.plot(iterations, median, color=colors[method], label=method)
        axis.fill_between(iterations, low, high, color=colors[method], alpha=0.15)
    axis.set_yscale("log")
    axis.set_xlabel("iteration")
    axis.set_ylabel("validation RMSE [mm]")
    axis.grid(alpha=0.3, which="both")
    axis.legend(ncol=3, fontsize=8)
    axis.set_title(title)
    return figure


def fig_residuals(details: Sequence[Mapping[str, Any]], methods: Sequence[str], title: str
                  ) -> Any:
    """Paper Fig. 5: residuals before and after, one trial per pose and all trials' spread."""
    plt = pyplot()
    colors = _colors(methods)
    figure, (left, right) = plt.subplots(1, 2, figsize=(13, 5), layout="constrained",
                                         gridspec_kw={"width_ratios": [3, 2]})
    first = details[0]
    poses = np.arange(1, len(first["before_residuals_mm"]) + 1)
    left.plot(poses, first["before_residuals_mm"], "k.--", label="before", linewidth=0.8)
    for method in methods:
        if method in first["methods"]:
            left.plot(poses, first["methods"][method]["residuals_mm"], ".-",
                      color=colors[method], label=method, linewidth=0.8)
    left.axhline(0.0, color="grey", linewidth=0.5)
    left.set_xlabel(f"validation pose (trial {first['trial']})")
    left.set_ylabel("cable-length residual [mm]")
    left.legend(ncol=3, fontsize=7)
    left.grid(alpha=0.3)
    labels = ["before", *[m for m in methods if m in first["methods"]]]
    spreads = [np.abs(np.concatenate([d["before_residuals_mm"] for d in details]))]
    spreads += [np.abs(np.concatenate([d["methods"][m]["residuals_mm"] for d in details
                                       if m in d["methods"]])) for m in labels[1:]]
    right.boxplot(spreads, showfliers=True, flierprops={"markersize": 2})
    right.set_xticks(np.arange(1, len(labels) + 1), labels, rotation=30, ha="right")
    right.set_yscale("log")
    right.set_ylabel("|residual| over all trials [mm]")
    right.grid(alpha=0.3, axis="y", which="both")
    figure.suptitle(title)
    return figure


def fig_parameter_error(details: Sequence[Mapping[str, Any]], methods: Sequence[str],
                        title: str) -> Any:
    """RMS over trials of the identifiable part of the parameter error, per unknown."""
    plt = pyplot()
    colors = _colors(methods)
    names = details[0]["parameter_names"]
    units = details[0]["parameter_units"]
    figure, axes = plt.subplots(2, 1, figsize=(12, 7), layout="constrained")
    for axis, unit in zip(axes, ("mm", "deg"), strict=True):
        columns = [i for i, u in enumerate(units) if u == unit]
        x = np.arange(len(columns))
        curves = {}
        for method in methods:
            errors = np.array([d["methods"][method]["parameter_error"] for d in details
                               if method in d["methods"]])
            if errors.size:
                curves[method] = np.sqrt(np.mean(errors[:, columns] ** 2, axis=0))
        # Unknowns wholly in the null space (θ6, α6…) have no identifiable error: round-off
        # would reach 1e-17, so the axis stops FLOOR below the largest error.
        floor = max((float(np.max(c)) for c in curves.values()), default=1.0) * FLOOR
        for method, rms in curves.items():
            axis.plot(x, np.maximum(rms, floor), "o-", color=colors[method], label=method,
                      markersize=3, linewidth=0.8)
        axis.set_xticks(x, [names[i] for i in columns], rotation=60, fontsize=8)
        axis.set_yscale("log")
        axis.set_ylim(bottom=floor * 0.8)
        axis.set_ylabel(f"RMS identifiable error [{unit}]")
        axis.grid(alpha=0.3, which="both")
    axes[0].legend(ncol=5, fontsize=7)
    axes[0].set_title(f"{title}: error off the null space (bottom row: not identifiable)")
    return figure


def fig_sweep(summary: Mapping[str, Any], methods: Sequence[str]) -> Any:
    """Validation RMSE and flange error against the truth per method across sweep points."""
    plt = pyplot()
    colors = _colors(methods)
    cases = summary["cases"]
    labels = [c["case"] for c in cases]
    x = np.arange(len(cases))
    figure, (left, right) = plt.subplots(1, 2, figsize=(12, 4.8), layout="constrained")
    for method in methods:
        present = [c for c in cases if method in c["truth"]]
        if len(present) != len(cases):
            continue
        rmse = [c["table6"][method]["rmse"]["mean"] for c in cases]
        flange = [c["truth"][method]["flange_error"]["mean"] for c in cases]
        crlb = [c["truth"][method]["crlb"]["mean"] for c in cases]
        left.plot(x, rmse, "o-", color=colors[method], label=method)
        right.plot(x, flange, "o-", color=colors[method], label=method)
    right.plot(x, crlb, "k--", label="Cramér–Rao bound")
    for axis, label in ((left, "validation RMSE [mm]"), (right, "flange error vs truth [mm]")):
        axis.set_xticks(x, labels, rotation=20, ha="right", fontsize=8)
        axis.set_yscale("log")
        axis.set_ylabel(label)
        axis.grid(alpha=0.3, which="both")
    right.legend(ncol=2, fontsize=7)
    return figure


Job = tuple[str, Callable[[], Any]]
"""A figure's file name and what draws it (returns the matplotlib figure)."""


def render(jobs: Sequence[Job]) -> list[tuple[str, bytes]]:
    """Each job's figure drawn and rendered as PNG, (name, bytes): a batch as a worker runs
    it."""
    return [(name, png_bytes(draw())) for name, draw in jobs]


def figure_jobs(summary: Mapping[str, Any],
                details_by_case: Mapping[str, Sequence[Mapping[str, Any]]],
                methods: Sequence[str]) -> list[Job]:
    """Every figure of a study, in the order they are listed (module docstring)."""
    jobs: list[Job] = []
    several = len(summary["cases"]) > 1
    for index, case in enumerate(summary["cases"], start=1):
        details = details_by_case.get(case["case"], [])
        if not details:
            continue
        suffix = f"-{index}" if several else ""
        title = f"{summary['scenario']}" + (f" — {case['case']}" if case["case"] else "") + \
            f" ({case['trials']} trials)"
        jobs += [
            (f"fig3_metrics{suffix}.png", partial(fig_metrics, case["table6"], title=title)),
            (f"fig4_convergence{suffix}.png",
             partial(fig_convergence, details, methods, title=title)),
            (f"fig5_residuals{suffix}.png", partial(fig_residuals, details, methods, title=title)),
            (f"parameter_error{suffix}.png",
             partial(fig_parameter_error, details, methods, title=title)),
        ]
    if several:
        jobs.append(("sweep.png", partial(fig_sweep, summary, methods)))
    return jobs


def write_figures(folder: str | Path, summary: Mapping[str, Any],
                  details_by_case: Mapping[str, Sequence[Mapping[str, Any]]],
                  methods: Sequence[str], stream: TextIO | None = None,
                  executor: Executor | None = None) -> list[str]:
    """Draw every figure of a study, with a progress bar of them on ``stream`` (stderr by
    default: a figure took about a second on a 2-core VM, and a study of ten methods was
    silent for 6 s after its last trial without it); returns the file names written.

    With an ``executor`` of several workers forked from this process (local processes on
    Linux, which start at once with what this process loaded) the figures are drawn there, one
    a batch, and written here as each arrives: a worker writes nothing into the folder, where
    one stopped mid-write would leave its temporary file. Elsewhere they are drawn here: a Dask
    cluster, stopped after the trials, takes seconds to start again, and a spawned worker
    imports twin and matplotlib anew."""
    folder = Path(folder)
    jobs = figure_jobs(summary, details_by_case, methods)
    if not jobs:
        return []
    progress = Progress(len(jobs), stream=stream, label="figures")
    try:
        with closing(_rendered(jobs, executor)) as batches:
            for batch in batches:
                for name, png in batch:
                    write_atomic(folder / name, png)
                    progress.advance()
    finally:
        progress.close()
    return [name for name, _ in jobs]


def _rendered(jobs: list[Job], executor: Executor | None
              ) -> Generator[list[tuple[str, bytes]], None, None]:
    """The jobs' PNGs, a batch at a time as they are drawn (:func:`write_figures`)."""
    if executor is None or not executor.forks or executor.workers < 2 or len(jobs) < 2:
        for job in jobs:
            yield render([job])
        return
    with executor, closing(executor.run(render, [[job] for job in jobs])) as work:
        yield from work
