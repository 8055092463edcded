"""Did a metric get worse than in a baseline study? Paired by trial, tested with Wilcoxon.

The baseline is an earlier study of the same scenario seed (another folder: another commit, a
changed solver or setting). Trial k of both drew the same perturbation, poses and noise, so the
two studies are compared trial by trial: for each sweep point, method and metric named in the
method's expectations, the paired differences d = this study − baseline.

- **Which way is worse** is the expectation's operator: ``<=``/``<`` bound the column from above,
  so higher is worse; ``>=``/``>`` the other way. A column bounded both ways is compared once per
  direction.
- **Test**: Wilcoxon signed-rank (:func:`scipy.stats.wilcoxon`), **one-sided**, alternative
  "this study is worse", on the trials that changed (differences within :data:`TIE_RTOL` of the
  values are ties and left out, as in Wilcoxon's own treatment of zeros). The direction is fixed
  by the expectation before looking at the data, which is what makes one-sided legitimate. Its
  smallest p-value is 2⁻ⁿ: below :data:`MIN_CHANGED` changed trials no result can reach
  p < 0.05 (two-sided would need one more), and the comparison says so instead of passing.
- **Size**: the median paired difference relative to the baseline's median (for the boolean
  ``converged``: the change of its share relative to the baseline's share).
- **Regression**: worse by more than the tolerance (relative, 5 % by default) *and* p < 0.05.

Pairs with a non-finite value on either side are left out and counted.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np

from twin.errors import InputError
from twin.study.expect import Expectation
from twin.study.rows import BOOLEAN_COLUMNS, TrialRow
from twin.study.statistics import SIGNIFICANCE, TIE_RTOL
from twin.study.store import TrialKey

MIN_CHANGED = math.ceil(-math.log2(SIGNIFICANCE))
"""Fewest changed trials with which a one-sided signed-rank test can give p < 0.05 (2⁻⁵)."""
MOVED = 3
"""Trials named as those that moved most."""
VERDICTS = ("pass", "regression", "inconclusive")


class Metric(NamedTuple):
    """A column of one method compared with the baseline, and which way is better."""

    method: str
    column: str
    lower_is_better: bool


class Comparison(NamedTuple):
    """One sweep point × method × metric compared with the baseline."""

    case: str
    """Sweep point label ("" without a sweep)."""
    method: str
    column: str
    lower_is_better: bool
    trials: int
    """Pairs compared (both values finite)."""
    changed: int
    """Pairs that are not ties: the n of the signed-rank test."""
    nonfinite: int
    """Pairs left out for a non-finite value."""
    median_difference: float
    """Median of this study − baseline, in the column's unit (NaN without pairs)."""
    relative: float
    """The change relative to the baseline (signed like the difference; NaN without pairs)."""
    p_value: float | None
    """One-sided p-value that this study is worse; None when nothing changed."""
    verdict: str
    """One of :data:`VERDICTS`."""
    moved: tuple[tuple[int, float], ...]
    """Up to :data:`MOVED` (trial, difference) pairs that got worse most, worst first."""

    @property
    def passed(self) -> bool:
        """False for a regression only (inconclusive is reported, not failed)."""
        return self.verdict != "regression"


def metrics_of(pairs: Sequence[tuple[str, Expectation]]) -> tuple[Metric, ...]:
    """The distinct (method, column, direction) of a check's expectations, in their order."""
    return tuple(dict.fromkeys(Metric(method, e.column, e.lower_is_better) for method, e in pairs))


def compare(case: str, metric: Metric, trials: Sequence[int], now: Sequence[float],
            before: Sequence[float], tolerance: float) -> Comparison:
    """Compare one metric's values trial by trial with the baseline's.

    Args:
        case: Sweep point label.
        metric: What is compared and which way is better.
        trials: Trial indices, shape (n,).
        now: This study's values, shape (n,) (booleans as 0/1).
        before: The baseline's values of the same trials, shape (n,).
        tolerance: Relative change that counts as a regression when significant (0.05: 5 %).
    """
    c, b = np.asarray(now, dtype=np.float64), np.asarray(before, dtype=np.float64)
    finite = np.isfinite(c) & np.isfinite(b)
    c, b, index = c[finite], b[finite], np.asarray(trials)[finite]
    nonfinite = int(np.count_nonzero(~finite))
    if c.size == 0:
        return Comparison(case, *metric, 0, 0, nonfinite, math.nan, math.nan, None,
                          "inconclusive", ())
    difference = c - b
    sign = 1.0 if metric.lower_is_better else -1.0
    worse = sign * difference
    if metric.column in BOOLEAN_COLUMNS:
        size, scale = float(np.mean(difference)), float(np.mean(b))
    else:
        size, scale = float(np.median(difference)), abs(float(np.median(b)))
    if scale > 0:
        relative = size / scale
    else:
        relative = math.copysign(math.inf, size) if abs(size) > 0 else 0.0
    changed = np.abs(difference) > TIE_RTOL * np.maximum(np.abs(c), np.abs(b))
    n_changed = int(np.count_nonzero(changed))
    p_value = None
    if n_changed:
        from scipy.stats import wilcoxon  # half a second of start-up: only tests need it

        with warnings.catch_warnings():
            # scipy warns that few samples use the exact distribution, or ties the normal one.
            warnings.simplefilter("ignore")
            p_value = float(wilcoxon(worse[changed], alternative="greater").pvalue)
    order = [i for i in np.argsort(-worse, kind="stable") if changed[i] and worse[i] > 0]
    moved = tuple((int(index[i]), float(difference[i])) for i in order[:MOVED])
    if sign * relative <= tolerance:
        verdict = "pass"
    elif n_changed < MIN_CHANGED:
        verdict = "inconclusive"
    else:
        verdict = "regression" if p_value is not None and p_value < SIGNIFICANCE else "pass"
    return Comparison(case, *metric, int(c.size), n_changed, nonfinite,
                      float(np.median(difference)), relative, p_value, verdict, moved)


def _label(key: TrialKey) -> str:
    return f"trial {key[1]}" + (f" of {key[0]}" if key[0] else "")


def paired_keys(seeds: Mapping[TrialKey, int], baseline: Mapping[TrialKey, list[TrialRow]],
                folder: str | Path) -> list[TrialKey]:
    """The trials of this study that the baseline holds, after checking that their seeds agree.

    Args:
        seeds: Seed of every trial of this study.
        baseline: The baseline's rows, grouped by trial.
        folder: The baseline folder, for messages.

    Raises:
        InputError: if no trial matches, or a matching trial has another seed.
    """
    common = [key for key in seeds if key in baseline]
    if not common:
        cases = sorted({case for case, _ in baseline}) or ["none"]
        raise InputError(
            f"no trial of this study in {folder} ({len(baseline)} trials, sweep points: "
            + ", ".join(repr(c) for c in cases) + ")",
            "a baseline study of the same scenario and sweep", source="--baseline")
    for key in common:
        theirs = baseline[key][0].seed
        if theirs != seeds[key]:
            raise InputError(f"{_label(key)} with seed {theirs} in {folder}, {seeds[key]} here",
                             "a baseline study with the same seeds (the same scenario seed), "
                             "so that trials pair", source="--baseline")
    return common


def require_methods(metrics: Sequence[Metric], baseline: Mapping[TrialKey, list[TrialRow]],
                    folder: str | Path) -> None:
    """Refuse a baseline without rows of a method compared.

    Raises:
        InputError: naming the method and listing the baseline's methods.
    """
    theirs = list(dict.fromkeys(row.method for group in baseline.values() for row in group))
    for metric in metrics:
        if metric.method not in theirs:
            raise InputError(f"no {metric.method} in {folder}", "a baseline with every method "
                             "compared; it has " + (", ".join(theirs) or "no rows"),
                             source="--baseline")


def compare_studies(
    metrics: Sequence[Metric], keys: Sequence[TrialKey],
    rows: Mapping[TrialKey, list[TrialRow]],
    baseline: Mapping[TrialKey, list[TrialRow]], tolerance: float,
) -> tuple[Comparison, ...]:
    """Every sweep point × metric compared with the baseline over the paired trials ``keys``
    (see :func:`paired_keys`), sweep points in the order of ``keys``."""
    def by_method(group: Mapping[TrialKey, list[TrialRow]]
                  ) -> dict[tuple[str, int, str], TrialRow]:
        return {(case, trial, row.method): row for (case, trial) in keys
                for row in group.get((case, trial), [])}

    now, before = by_method(rows), by_method(baseline)
    comparisons = []
    for case in dict.fromkeys(case for case, _ in keys):
        for metric in metrics:
            found = [(trial, now[key].number(metric.column), before[key].number(metric.column))
                     for c, trial in keys if c == case
                     for key in [(case, trial, metric.method)] if key in now and key in before]
            comparisons.append(compare(case, metric, [t for t, _, _ in found],
                                       [v for _, v, _ in found], [v for _, _, v in found],
                                       tolerance))
    return tuple(comparisons)
