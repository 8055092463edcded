"""Regenerate every table of figures in docs/methods.md and docs/studies.md from fresh runs.

Run by hand after changing a solver, a model or a scenario: ``make docs`` (or
``.venv/bin/python bench/docs_tables.py [--skip-bench]``). It

1. runs a fresh study of every regime scenario in scenarios/ (10 trials, every method) into
   ``out/docs/studies/`` (deleted first), and the bounds and geometric regimes again under the
   paper's stopping protocol;
2. replays M9 on every trial of every single-case regime to measure what its BIPSO stage
   changes after AMLM — after a converged AMLM, under the paper's 30 + 30, and after AMLM
   stopped early;
3. runs the benchmarks whose output the docs quote (``--skip-bench`` keeps the old output);
4. rewrites each block between ``<!-- BEGIN GENERATED name -->`` and
   ``<!-- END GENERATED name -->`` in the docs, each stamped with the commit it was measured at,
   and copies the paper study's convergence figure to docs/figures/.

The accuracy tables are deterministic (seeded): a second run at the same commit reproduces
them digit for digit. Times vary from run to run and machine to machine.
"""

from __future__ import annotations

import argparse
import csv
import datetime
import re
import shutil
import statistics
import subprocess
import sys
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from twin.calibration import make_problem
from twin.sim import Scenario, simulate
from twin.solvers.amlm import amlm
from twin.solvers.base import Tracker
from twin.solvers.bipso import bipso
from twin.stopping import Budget
from twin.study import load_study, run_study
from twin.study.executors.local import LocalProcesses
from twin.study.trial import TrialSpec, trial_seed, workspace
from twin.uncertainty import rms_distance
from twin.units import m_to_mm

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"
DOCS = ROOT / "docs"
TRIALS = 10
REGIMES = ("paper", "geometric", "bounds", "compliance", "outliers", "few_poses", "unknown_port",
           "noise_sweep")
"""Regime scenarios (``scenarios/<name>_irb120.toml``), in the order of the tables."""
PROTOCOL_REGIMES = ("bounds", "geometric")
"""Regimes also studied under the paper's stopping protocol."""
EARLY_STOPS = (3,)
"""AMLM iteration limits for the "stopped early" rows of the M9 table."""
BEST_WITHIN = 0.02
"""Methods within this fraction of the best mean are bold in the regime table."""


def commit() -> str:
    """The short hash of HEAD, with ``+changes`` when tracked files differ from it."""
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, check=True,
                          capture_output=True, text=True).stdout.strip()
    dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT,
                           check=True, capture_output=True, text=True).stdout.strip()
    return head + ("+changes" if dirty else "")


def stamp(what: str) -> str:
    """The line under every generated table."""
    today = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d")
    return (f"*{what} Measured at commit `{commit()}` on {today} by `make docs` "
            "(bench/docs_tables.py).*")


def replace_block(text: str, name: str, content: str) -> str:
    """``text`` with the generated block ``name`` replaced by ``content``."""
    pattern = re.compile(rf"(<!-- BEGIN GENERATED {re.escape(name)} -->\n).*?"
                         rf"(<!-- END GENERATED {re.escape(name)} -->)", re.DOTALL)
    if not pattern.search(text):
        raise SystemExit(f"docs: no generated block {name!r}")
    return pattern.sub(lambda m: m.group(1) + content.rstrip("\n") + "\n" + m.group(2), text)


def scenario_path(regime: str) -> Path:
    return SCENARIOS / f"{regime}_irb120.toml"


def run_regime(regime: str, folder: Path, stop: str | None = None) -> dict[str, Any]:
    """A fresh 10-trial study of every method; the summary document."""
    plan = load_study(scenario_path(regime), trials=TRIALS, methods=["all"], stop=stop)
    print(f"study {regime}{' (' + stop + ')' if stop else ''}: {len(plan.cases)} case(s)",
          file=sys.stderr, flush=True)
    return run_study(plan, folder, LocalProcesses(), stream=sys.stderr)


def fmt(value: float) -> str:
    """Three significant digits, as the tables print means."""
    return f"{value:.3g}"


def markdown_table(header: Sequence[str], rows: Iterable[Sequence[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


def label(method: str, table: dict[str, Any]) -> str:
    alias = table[method]["alias"]
    return f"{alias.upper()} {method}" if alias else method


# --- studies.md -------------------------------------------------------------------------------

def paper_replica(summary: dict[str, Any]) -> str:
    """Table 6 and 7 replicas with the paper's figures and the flange error against the truth."""
    case = summary["cases"][0]
    t6, t7, truth, paper = case["table6"], case["table7"], case["truth"], summary["paper"]

    def pm(stats: dict[str, float], digits: int = 3) -> str:
        return f"{stats['mean']:.{digits}f} ± {stats['std']:.{digits}f}"

    rows = [["before", "", pm(t6["before"]["rmse"]), pm(t6["before"]["mae"]),
             pm(t6["before"]["max"]), "", "", "", "2.177 / 2.006 / 3.99", ""]]
    for method, row in t6.items():
        if method == "before":
            continue
        alias = row["alias"]
        quoted = paper.get(alias, {})
        figures = " / ".join(f"{quoted[k]:g}" for k in ("rmse", "mae", "max") if k in quoted)
        test = t7["tests"].get(method)
        rows.append([
            method, alias.upper(), pm(row["rmse"]), pm(row["mae"]), pm(row["max"]),
            pm(truth[method]["flange_error"]),
            f"{row['seconds']['mean']:.3f}",
            "" if test is None else f"{test['p_value']:.2g}",
            figures, f"{quoted['seconds']:g}" if "seconds" in quoted else "",
        ])
    table = markdown_table(
        ["method", "paper", "RMSE [mm]", "\"STD\" (MAE) [mm]", "MAX [mm]", "flange error [mm]",
         "time [s]", "Wilcoxon p vs M9", "paper RMSE / STD / MAX", "paper time"], rows)
    bound = truth["lm"]["crlb"]["mean"]
    return (table + f"\n\nCramér–Rao bound of the flange error from the noise alone: "
            f"{bound:.4f} mm.\n\n" + stamp(f"`twin study scenarios/paper_irb120.toml`, "
                                          f"{TRIALS} trials, mean ± std, paper protocol."))


def regimes_table(summaries: dict[str, dict[str, Any]]) -> str:
    """Every regime: validation RMSE, flange error and its ratio to the bound, per method."""
    first = summaries[REGIMES[0]]["cases"][0]["table6"]
    methods = [m for m in first if m != "before"]
    header = ["regime", "metric [mm]", "before", *(label(m, first) for m in methods), "bound"]
    rows = []
    for regime in REGIMES:
        for case in summaries[regime]["cases"]:
            t6, truth = case["table6"], case["truth"]
            name = regime.replace("_", " ") + (f", {case['case']}" if case["case"] else "")
            metrics: list[tuple[str, Callable[[str], float], str, str]] = [
                ("validation RMSE", lambda m, t6=t6: t6[m]["rmse"]["mean"],
                 fmt(t6["before"]["rmse"]["mean"]), ""),
                ("flange error", lambda m, truth=truth: truth[m]["flange_error"]["mean"], "",
                 fmt(truth[methods[0]]["crlb"]["mean"])),
                ("flange / bound, median", lambda m, truth=truth:
                 truth[m]["crlb_ratio"]["median"], "", ""),
            ]
            for metric, value, before, bound in metrics:
                values = {m: value(m) for m in methods}
                best = min(values.values())
                cells = [f"**{fmt(v)}**" if v <= best * (1 + BEST_WITHIN) else fmt(v)
                         for v in values.values()]
                rows.append([name, metric, before, *cells, bound])
    return (markdown_table(header, rows) + "\n\n" + stamp(
        f"`twin study scenarios/<regime>_irb120.toml`, {TRIALS} trials per case, every method; "
        f"means (ratios: medians); bold: within {BEST_WITHIN:.0%} of the best."))


# --- methods.md -------------------------------------------------------------------------------

def protocols_table(converge: dict[str, dict[str, Any]], paper: dict[str, dict[str, Any]]
                    ) -> str:
    """The same regimes under both stopping protocols, per method."""
    rows = []
    for regime in PROTOCOL_REGIMES:
        by_protocol = {"converge": converge[regime]["cases"][0],
                       "paper": paper[regime]["cases"][0]}
        t6 = by_protocol["converge"]["table6"]
        for method in (m for m in t6 if m != "before"):
            cells = [regime, label(method, t6)]
            for case in by_protocol.values():
                row, truth = case["table6"][method], case["truth"][method]
                reasons = ", ".join(f"{r} ×{n}" for r, n in row["stop_reasons"].items())
                cells += [fmt(truth["crlb_ratio"]["median"]), fmt(row["rmse"]["mean"]),
                          f"{row['iterations']['mean']:.0f}", reasons]
            rows.append(cells)
    header = ["regime", "method",
              "converge: flange / bound (median)", "validation RMSE [mm]", "iterations",
              "stopped by",
              "paper: flange / bound (median)", "validation RMSE [mm]", "iterations",
              "stopped by"]
    return markdown_table(header, rows) + "\n\n" + stamp(
        f"`twin study scenarios/<regime>_irb120.toml [--stop paper]`, {TRIALS} trials.")


class StageChange(NamedTuple):
    """What M9's BIPSO stage changed on one trial, after one kind of AMLM stage."""

    regime: str
    start: str
    amlm_iterations: int
    first_improvement: int | None
    """BIPSO iteration at which f first fell below the AMLM result's by more than round-off."""
    f_relative: float
    """(f after − f before) / f before."""
    validation_mm: float
    """Validation RMSE after − before, mm."""
    flange_mm: float
    """Flange error against the truth after − before, mm."""
    flange_before_mm: float


LONG = Budget(stall_iterations=0).stage()
"""A BIPSO stage of 200 iterations with no stall test."""
STARTS: dict[str, tuple[Budget, Budget]] = {
    "M9, converge protocol (AMLM to convergence, BIPSO until it stalls)":
        (Budget().stage(), Budget().stage()),
    "M9, paper protocol (30 + 30)": (Budget.paper().stage(), Budget.paper().stage()),
    f"AMLM converged, BIPSO {LONG.max_iterations} iterations": (Budget().stage(), LONG),
    **{f"AMLM stopped at {k} iterations, BIPSO 30": (Budget.named("converge", k),
                                                      Budget.paper().stage())
       for k in EARLY_STOPS},
    **{f"AMLM stopped at {k} iterations, BIPSO {LONG.max_iterations}":
       (Budget.named("converge", k), LONG) for k in EARLY_STOPS},
}
"""Budgets of the AMLM and BIPSO stages of each row: the first two rows are M9 itself."""
ROUND_OFF = 1e-9
"""Relative decrease of f below which a BIPSO "improvement" is re-evaluation round-off."""


def bipso_changes(regime: str, scenario: Scenario, trial: int) -> list[StageChange]:
    """Replay M9's two stages on one trial of a regime, for every kind of AMLM stage."""
    seed = trial_seed(scenario.seed, trial)
    sim = simulate(scenario, seed)
    problem = make_problem(sim.robot, sim.measurements, sim.port_nominal_m, seed=seed,
                           estimate_port=scenario.estimate_port,
                           estimate_offset=scenario.estimate_offset).problem
    q_workspace = workspace(TrialSpec(scenario, (), 500))
    model = problem.model

    def measure(x: np.ndarray) -> tuple[float, float, float]:
        f = float(np.mean(model.residuals(x, problem.train) ** 2))
        validation = float(np.sqrt(np.mean(model.residuals(x, problem.validation) ** 2)))
        flange = rms_distance(model.flange_positions(x, model.poses(q_workspace)),
                              sim.true_robot.flange_positions(q_workspace))
        return f, float(m_to_mm(validation)), float(m_to_mm(flange))

    changes = []
    for start, (amlm_budget, bipso_budget) in STARTS.items():
        tracker = Tracker(problem, "amlm-bipso")
        first = amlm(tracker, problem.x0, amlm_budget)
        iterations = tracker.iterations
        second = bipso(tracker, first.x, bipso_budget, np.random.default_rng(seed))
        (f0, v0, e0), (f1, v1, e1) = measure(first.x), measure(second.x)
        f_stage = np.array([record.f_m2 for record in tracker.history[iterations + 1:]])
        better = np.flatnonzero(f_stage < f0 * (1 - ROUND_OFF))
        changes.append(StageChange(regime, start, iterations,
                                   int(better[0]) + 1 if better.size else None,
                                   (f1 - f0) / f0, v1 - v0, e1 - e0, e0))
    return changes


def _bipso_job(job: tuple[str, int]) -> list[StageChange]:
    regime, trial = job
    scenario = load_study(scenario_path(regime)).cases[0].scenario
    return bipso_changes(regime, scenario, trial)


def bipso_table() -> str:
    """Per regime and kind of AMLM stage: whether and when BIPSO improved, and what it changed."""
    regimes = [r for r in REGIMES if len(load_study(scenario_path(r)).cases) == 1]
    jobs = [(regime, trial) for regime in regimes for trial in range(TRIALS)]
    print(f"M9 stages: {len(jobs)} trials", file=sys.stderr, flush=True)
    with ProcessPoolExecutor() as pool:
        changes = [c for batch in pool.map(_bipso_job, jobs) for c in batch]
    rows = []
    for start in STARTS:
        for regime in regimes:
            chosen = [c for c in changes if c.regime == regime and c.start == start]
            improved = [c.first_improvement for c in chosen if c.first_improvement is not None]
            rows.append([
                start, regime.replace("_", " "),
                f"{statistics.median(c.amlm_iterations for c in chosen):.0f}",
                f"{len(improved)} / {len(chosen)}",
                f"{statistics.median(improved):.0f}" if improved else "",
                f"{statistics.median(c.f_relative for c in chosen):+.2g}",
                f"{statistics.median(c.validation_mm for c in chosen):+.2g}",
                f"{statistics.median(c.flange_mm for c in chosen):+.2g}",
                f"{statistics.median(c.flange_before_mm for c in chosen):.3g}",
            ])
    header = ["AMLM stage, BIPSO stage", "regime", "AMLM iterations (median)",
              "trials BIPSO improved", "first improvement at BIPSO iteration (median)",
              "Δf / f (median)", "Δ validation RMSE [mm] (median)",
              "Δ flange error [mm] (median)", "flange error after AMLM [mm] (median)"]
    return markdown_table(header, rows) + "\n\n" + stamp(
        f"Every trial of each regime ({TRIALS}), an AMLM stage then a BIPSO stage centred on "
        "its result (the first two rows are M9 itself); Δ = after BIPSO − after AMLM (negative: "
        f"BIPSO helped); improvements below {ROUND_OFF:g} of f (re-evaluation round-off) do not "
        "count.")


def bench_output(script: str, *args: str) -> str:
    """The output of a benchmark script run now, as a fenced block with its command."""
    command = [sys.executable, str(ROOT / "bench" / script), *args]
    print("bench:", " ".join(command[1:]), file=sys.stderr, flush=True)
    output = subprocess.run(command, cwd=ROOT, check=True, capture_output=True,
                            text=True).stdout
    shown = " ".join(["python", f"bench/{script}", *args])
    return (f"```\n$ {shown}\n{output.rstrip()}\n```\n\n"
            + stamp("Times vary from run to run; ratios are measured side by side."))


# --- measurements.md --------------------------------------------------------------------------

RIGS = ("eyelet", "tracker", "fixed_points", "stations", "unknown_port", "outliers")
"""Rig regimes of docs/measurements.md, each studied with its own [study] methods."""
RIG_COLUMNS = (("flange_error_mm", "flange [mm]", "mean"),
               ("flange_error_gauge_free_mm", "flange mod gauge [mm]", "mean"),
               ("crlb_ratio_gauge_free", "flange / bound", "median"),
               ("point_error_mm", "point mod gauge [mm]", "mean"),
               ("point_crlb_ratio", "point / bound", "median"),
               ("point_crlb_ratio", "point / bound, max", "max"))
STATIONS = (("front", (600.0, -400.0, 100.0)), ("left", (300.0, 600.0, 50.0)),
            ("back", (-500.0, -300.0, 150.0)))
STATION_POSES = 120
"""Poses of every configuration of the stations table, shared evenly between its stations."""


def rigs_table(folder: Path) -> str:
    """Every rig regime: errors against the truth raw and modulo the gauge, and their ratios to
    the Cramér–Rao bound, per method (fresh studies, each regime's own methods)."""
    rows = []
    for regime in RIGS:
        plan = load_study(scenario_path(regime), trials=TRIALS)
        print(f"study {regime} (rigs)", file=sys.stderr, flush=True)
        run_study(plan, folder / regime, LocalProcesses(), stream=sys.stderr)
        with (folder / regime / "results.csv").open(encoding="utf-8") as handle:
            found = list(csv.DictReader(handle))
        for method in plan.methods:
            values = {column: [float(r[column]) for r in found if r["method"] == method]
                      for column, _, _ in RIG_COLUMNS}
            cells = [fmt({"mean": statistics.fmean, "median": statistics.median,
                          "max": max}[stat](values[column])) for column, _, stat in RIG_COLUMNS]
            rows.append([regime.replace("_", " "), method, *cells])
    header = ["regime", "method", *(title for _, title, _ in RIG_COLUMNS)]
    return markdown_table(header, rows) + "\n\n" + stamp(
        f"`twin study scenarios/<regime>_irb120.toml`, {TRIALS} trials, the methods of each "
        "scenario's [study] table; errors over 1000 workspace poses (means; ratios to the "
        "Cramér–Rao bound: medians, and the largest); the point is the measured one (eyelet, "
        "tracker target, ball; the flange centre for a cable without attachment).")


def stations_table() -> str:
    """What extra stations change: rank, σ of the D-H lengths and the bound, for the same
    number of random feasible poses shared between 1, 2 or 3 stations, ports measured or
    estimated."""
    from twin.calibration import make_model
    from twin.design import score_poses
    from twin.gauge import unobservable_motions
    from twin.identifiability import measurement_identifiability
    from twin.rig import Rig
    from twin.robot import default_robot
    from twin.sim.poses import PoseConstraints, sample_poses
    from twin.sim.twin import Twin
    from twin.synthetic import random_poses
    from twin.uncertainty import base_covariance, parameter_sigma
    from twin.units import mm_to_m

    robot = default_robot()
    rng = np.random.default_rng(0)
    sigma_m = float(mm_to_m(0.01))
    q_workspace = random_poses(robot, 1000, rng)
    ports = np.array([mm_to_m(port) for _, port in STATIONS])
    names = tuple(name for name, _ in STATIONS)
    drawn = [sample_poses(Twin.build(robot, port), STATION_POSES, PoseConstraints(), rng)
             for port in ports]
    rows = []
    for count in (1, 2, 3):
        share, extra = divmod(STATION_POSES, count)
        sizes = [share + (k < extra) for k in range(count)]
        q = np.concatenate([drawn[k][: sizes[k]] for k in range(count)])
        port = np.repeat(np.arange(count), sizes)
        configurations = [(), names[:count]] + ([names[1:count]] if count > 1 else [])
        for estimated in configurations:
            rig = Rig(ports[:count], names[:count], estimated_ports=estimated)
            model = make_model(robot, rig, estimate_port=bool(estimated))
            x0 = np.zeros(model.n_params)
            data = model.poses(q, port)
            ident = measurement_identifiability(model, x0, data)
            covariance = base_covariance(model.identifiable_jacobian(x0, data)[1], ident.base,
                                         sigma_m)
            sigma = parameter_sigma(covariance, ident.base)[model.slice("dh")]
            lengths = sigma[model.robot.structure.is_length.ravel()]
            score = score_poses(model, x0, q, ident.base_mask, sigma_m, q_workspace, port)
            gauge = unobservable_motions(model, x0, ident.null_space, q_workspace)
            told = "every port estimated" if len(estimated) == count else (
                "ports measured" if not estimated else "first port measured, others estimated")
            rows.append([str(count), told, f"{ident.rank} of {ident.n_params}",
                         fmt(ident.condition),
                         fmt(float(m_to_mm(np.nanmedian(lengths)))),
                         fmt(float(m_to_mm(score.flange_rms_m))),
                         gauge.describe()])
    header = ["stations", "ports", "rank", "condition", "median σ of a D-H length [mm]",
              "bound, flange RMS [mm]", "unobservable"]
    return markdown_table(header, rows) + "\n\n" + stamp(
        f"IRB 120 at the nominal geometry, {STATION_POSES} feasible random poses (the twin's "
        "default constraints) shared evenly between the stations, σ = 0.01 mm; σ and the bound "
        "(Cramér–Rao over 1000 workspace poses) leave the unobservable motions out.")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "out" / "docs",
                        help="where the studies run (deleted first)")
    parser.add_argument("--skip-bench", action="store_true",
                        help="keep the benchmark output blocks as they are")
    args = parser.parse_args()
    studies = args.out / "studies"
    shutil.rmtree(studies, ignore_errors=True)
    converge = {regime: run_regime(regime, studies / regime) for regime in REGIMES}
    paper = {regime: run_regime(regime, studies / f"{regime}-paper", stop="paper")
             for regime in PROTOCOL_REGIMES}
    blocks = {
        "studies.md": {"paper-replica": paper_replica(converge["paper"]),
                       "regimes": regimes_table(converge)},
        "methods.md": {"protocols": protocols_table(converge, paper),
                       "m9-bipso-stage": bipso_table()},
        "measurements.md": {"rigs": rigs_table(studies / "rigs"),
                            "stations": stations_table()},
    }
    if not args.skip_bench:
        blocks["methods.md"]["bench-solvers"] = bench_output(
            "bench_solvers.py", "--repeat", "3", "--large-errors", "8")
        blocks["methods.md"]["bench-calibration"] = bench_output("bench_calibration.py")
        blocks["studies.md"]["bench-study"] = bench_output("bench_study.py")
    for name, generated in blocks.items():
        path = DOCS / name
        text = path.read_text(encoding="utf-8")
        for block, content in generated.items():
            text = replace_block(text, block, content)
        path.write_text(text, encoding="utf-8")
        print(f"written: {path.relative_to(ROOT)}", file=sys.stderr)
    figure = studies / "paper" / "fig4_convergence.png"
    shutil.copyfile(figure, DOCS / "figures" / "methods_paper_convergence.png")


if __name__ == "__main__":
    main()
