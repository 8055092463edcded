"""A check: run (or resume) a study, then hold its results to the scenario's expectations.

::

    from twin.study.check import check

    report = check("scenarios/geometric_irb120.toml", "out/check", trials=5, methods=["lm"])
    print(report.text)                  # one line per expectation, and a total line
    assert report.passed

The study runs exactly as `twin study` runs it (same folder, resume, summary and figures);
the expectations (:mod:`twin.study.expect`) are evaluated per sweep point over the study's
trials, and with a baseline study every metric they name is compared trial by trial
(:mod:`twin.study.baseline`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple, TextIO

from twin.choices import DEFAULT_TOLERANCE, MAX_TOLERANCE
from twin.errors import InputError
from twin.io.lock import folder_lock
from twin.report.display import percent
from twin.study.baseline import (
    MIN_CHANGED,
    Comparison,
    compare_studies,
    metrics_of,
    paired_keys,
    require_methods,
)
from twin.study.definition import StudyPlan, load_study
from twin.study.executors import Executor, open_executor
from twin.study.expect import (
    Expectation,
    measure_expectation,
    parse_expect_table,
    read_expect_file,
)
from twin.study.rows import TrialRow
from twin.study.runner import run_trials, write_report
from twin.study.statistics import SIGNIFICANCE
from twin.study.store import TrialKey, read_results
from twin.study.trial import trial_seed

ExpectSource = str | Path | Mapping[str, Sequence[str]]
"""An expectations file, or an ``[expect]`` table as a mapping."""


class ExpectationResult(NamedTuple):
    """One expectation of one method at one sweep point, measured."""

    case: str
    """Sweep point label ("" without a sweep)."""
    method: str
    expectation: Expectation
    value: float
    """The statistic over the trials, in the column's unit; NaN when it cannot be measured."""
    trials: int
    nonfinite: int
    """Trials with a NaN or infinite value in the column (the expectation then fails)."""
    note: str
    """Why ``value`` is NaN, or ""."""
    passed: bool


@dataclass(frozen=True)
class CheckReport:
    """What a check found.

    Attributes:
        scenario: The scenario's name.
        source: The scenario file.
        folder: The study folder.
        trials: Trials per sweep point.
        methods: The study's methods.
        results: Every expectation measured: by sweep point, then method in the study's
            order, then expectation in the table's order.
        baseline: The baseline folder, or None.
        comparisons: With a baseline: each sweep point × method × metric compared.
        tolerance: Relative worsening a significant change may have without being a regression.
    """

    scenario: str
    source: Path
    folder: Path
    trials: int
    methods: tuple[str, ...]
    results: tuple[ExpectationResult, ...]
    baseline: Path | None = None
    comparisons: tuple[Comparison, ...] = ()
    tolerance: float = DEFAULT_TOLERANCE

    def __post_init__(self) -> None:
        if not (math.isfinite(self.tolerance) and self.tolerance >= 0):
            raise ValueError("tolerance: expected a finite number >= 0")
        if self.comparisons and self.baseline is None:
            raise ValueError("comparisons: expected a baseline folder with them")

    @property
    def passed(self) -> bool:
        """Every expectation holds and no metric regressed against the baseline."""
        return all(r.passed for r in self.results) and all(c.passed for c in self.comparisons)

    @property
    def swept(self) -> bool:
        """Whether the study has sweep points (their labels then head every line)."""
        return any(r.case for r in self.results)

    def total(self) -> str:
        """The total line."""
        failed = sum(not r.passed for r in self.results)
        text = (f"total: {len(self.results)} expectations, {len(self.results) - failed} passed, "
                f"{failed} failed")
        if self.baseline is not None:
            count = {verdict: sum(c.verdict == verdict for c in self.comparisons)
                     for verdict in ("pass", "regression", "inconclusive")}
            text += (f"; {len(self.comparisons)} compared with the baseline, {count['pass']} "
                     f"passed, {count['regression']} regressed, {count['inconclusive']} "
                     "inconclusive")
        return text + f" -> {'PASS' if self.passed else 'FAIL'}"

    def lines(self) -> list[str]:
        """The report: one line per expectation, the baseline comparisons, the total line."""
        head = ["case"] if self.swept else []
        rows = [([r.case] if self.swept else []) + [
            r.method, r.expectation.text, measured_text(r), "PASS" if r.passed else "FAIL"]
            for r in self.results]
        lines = [f"{self.scenario}: {self.trials} trials" + (" per sweep point" if self.swept
                                                               else "")
                 + f", study in {self.folder}"]
        lines += _table([*head, "method", "expectation", "measured", "verdict"], rows)
        if self.baseline is not None:
            lines += ["", *self._baseline_lines()]
        return [*lines, self.total()]

    def _baseline_lines(self) -> list[str]:
        n = max((c.trials for c in self.comparisons), default=0)
        lines = [f"baseline {self.baseline}: {n} paired trials, one-sided Wilcoxon signed-rank "
                 "test that this study is worse",
                 f"regression: p < {SIGNIFICANCE:g} and worse by more than "
                 f"{percent(self.tolerance)} (median paired difference / the baseline's median)"]
        # Nothing changed is a definite answer; a few changes are not.
        few = [c for c in self.comparisons if 0 < c.changed < MIN_CHANGED]
        if few:
            lines.append(
                f"note: {len(few)} of {len(self.comparisons)} comparisons have fewer than "
                f"{MIN_CHANGED} changed trials, with which the test cannot reach p < "
                f"{SIGNIFICANCE:g} (its smallest p is 2^-n): where they got worse they are "
                f"INCONCLUSIVE, not passed; run {MIN_CHANGED} trials or more to decide")
        head = ["case"] if self.swept else []
        rows = []
        for c in self.comparisons:
            p = "" if c.p_value is None else f"{c.p_value:.3g}"
            moved = ", ".join(f"trial {trial} {difference:+.4g}" for trial, difference in c.moved)
            rows.append(([c.case] if self.swept else []) + [
                c.method, c.column, "lower" if c.lower_is_better else "higher",
                f"{c.trials}" + (f" (+{c.nonfinite} non-finite)" if c.nonfinite else ""),
                f"{c.changed}", f"{c.median_difference:+.4g}", percent(c.relative, 1, sign=True), p,
                c.verdict.upper(), moved])
        lines += _table([*head, "method", "metric", "better", "pairs", "changed",
                         "median diff", "relative", "p", "verdict", "worse most"], rows)
        return lines

    @property
    def text(self) -> str:
        """:meth:`lines` as one string."""
        return "\n".join(self.lines()) + "\n"


def measured_text(result: ExpectationResult) -> str:
    """The measured value as reported: enough digits to tell it from the threshold."""
    if not math.isfinite(result.value):
        return f"n/a ({result.note})"
    text = f"{result.value:.4g}"
    if text == f"{result.expectation.value:.4g}":
        text = f"{result.value:.10g}"
    return text


def _table(head: list[str], rows: list[list[str]]) -> list[str]:
    widths = [max(len(row[i]) for row in [head, *rows]) for i in range(len(head))]
    return ["  ".join(cell.ljust(width) for cell, width in zip(row, widths, strict=True))
            .rstrip() for row in [head, *rows]]


def load_expectations(plan: StudyPlan, expect: ExpectSource | None
                      ) -> tuple[tuple[str, Expectation], ...]:
    """The (method, expectation) pairs of a check: from ``expect`` (a file or a mapping), which
    replaces the scenario's ``[expect]`` table, else from that table.

    Raises:
        InputError: if there are none, or one is malformed or names a method not in the study.
    """
    source: str | Path
    if expect is None:
        table: Any = plan.cases[0].scenario.expect
        source = plan.source
        if not table:
            raise InputError("no [expect] table", "expectations: an [expect] table in the "
                             "scenario, or --expect FILE", source=plan.source)
    elif isinstance(expect, Mapping):
        table, source = expect, "expect"
    else:
        table, source = read_expect_file(expect), Path(expect)
    return parse_expect_table(table, plan.methods, source)


def evaluate(pairs: Sequence[tuple[str, Expectation]], rows: Sequence[TrialRow],
             cases: Sequence[str], methods: Sequence[str]) -> tuple[ExpectationResult, ...]:
    """Every expectation measured over each sweep point's trials; by sweep point, then method
    in the study's order, then expectation in the table's order."""
    ordered = sorted(pairs, key=lambda pair: methods.index(pair[0]))
    results = []
    for case in cases:
        for method, expectation in ordered:
            values = [r.number(expectation.column) for r in rows
                      if r.case == case and r.method == method]
            value, trials, nonfinite, note = measure_expectation(expectation, values)
            results.append(ExpectationResult(case, method, expectation, value, trials,
                                             nonfinite, note, expectation.holds(value)))
    return tuple(results)


def check(
    scenario: str | Path,
    out: str | Path,
    *,
    trials: int | None = None,
    methods: Sequence[str] | None = None,
    expect: ExpectSource | None = None,
    baseline: str | Path | None = None,
    tolerance: float = DEFAULT_TOLERANCE,
    executor: Executor | None = None,
    figures: bool = True,
    stream: TextIO | None = None,
) -> CheckReport:
    """Run or resume the study of ``scenario`` in ``out`` as `twin study` does, then evaluate
    its expectations and, with ``baseline``, compare it with that study trial by trial.

    Everything the user gave is validated before a trial runs.

    Args:
        scenario: The scenario TOML.
        out: The study folder (created, or resumed when it holds this study).
        trials: Trials per sweep point (default: ``[study] trials``, else 10).
        methods: Method names or aliases (default: ``[study] methods``, else all).
        expect: An expectations file (a TOML file with an ``[expect]`` table) or such a table as
            a mapping; replaces the scenario's ``[expect]`` table.
        baseline: The folder of an earlier study of the same scenario seed.
        tolerance: Relative worsening a significant change may have without being a
            regression (0.05: 5 %).
        executor: Where trials run; local processes, one per core, by default.
        figures: Whether to draw the study's figures, as `twin study` does; the summary is
            written either way (a later `twin study` of the folder draws them, running nothing).
        stream: Where the progress bar goes; stderr by default.

    Raises:
        InputError: for a mistake in the scenario, the expectations, the baseline or a value.
    """
    if isinstance(tolerance, bool) or not isinstance(tolerance, int | float) \
            or not 0 <= tolerance <= MAX_TOLERANCE:
        raise InputError(f"{tolerance!r}", f"a relative tolerance from 0 to {MAX_TOLERANCE:g} "
                         f"({MAX_TOLERANCE:.0%}), e.g. 5% (0.05)", source="--tolerance")
    names = [methods] if isinstance(methods, str) else None if methods is None else list(methods)
    plan = load_study(scenario, trials=trials, methods=names)
    pairs = load_expectations(plan, expect)
    base_rows: dict[TrialKey, list[TrialRow]] = {}
    paired: list[TrialKey] = []
    if baseline is not None:
        base_rows = read_results(baseline)
        seeds = {key: trial_seed(plan.seed, key[1]) for key in plan.keys}
        paired = paired_keys(seeds, base_rows, baseline)
        require_methods(metrics_of(pairs), base_rows, baseline)
    if executor is None:
        executor = open_executor()
    with folder_lock(out, "twin check"):
        store = run_trials(plan, out, executor, stream=stream)
        write_report(plan, store, figures=figures, stream=stream, executor=executor)
    rows = store.rows(plan.keys)
    grouped: dict[TrialKey, list[TrialRow]] = {}
    for row in rows:
        grouped.setdefault((row.case, row.trial), []).append(row)
    comparisons = compare_studies(metrics_of(pairs), paired, grouped, base_rows, tolerance) \
        if baseline is not None else ()
    return CheckReport(
        scenario=plan.cases[0].scenario.name, source=plan.source, folder=Path(out),
        trials=plan.trials, methods=plan.methods,
        results=evaluate(pairs, rows, [case.label for case in plan.cases], plan.methods),
        baseline=None if baseline is None else Path(baseline), comparisons=comparisons,
        tolerance=float(tolerance))
