"""A study's statistics: the paper's Table 6 and Table 7 replicas and the truth table.

- **Table 6**: mean ± std over trials of each method's validation RMSE, MAE (labelled "STD" as
  in the paper, whose eq. 32 "STD" is a mean absolute error), MAX and time, beside the paper's
  values (method-notes §3) where the paper gives them.
- **Table 7**: Wilcoxon signed-rank test (:func:`scipy.stats.wilcoxon`, two-sided) of M9
  against every other method on the validation RMSE, paired by trial. A method that is not in
  the study is named as missing rather than left out silently.
- **Truth table**: the RMS flange-position error over the workspace against the true geometry,
  its Cramér–Rao bound and their ratio (1 = as good as any unbiased estimator can be).

Every number is in mm or s. :func:`summarize` gathers them in the summary document (written as
`summary.json`); :mod:`twin.study.markdown` renders it (`summary.md`).
"""

from __future__ import annotations

import warnings
from collections import Counter
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from twin.errors import UnknownChoiceError
from twin.solvers import SOLVERS, get_solver
from twin.study.rows import TrialRow

PAPER_REFERENCE = "m9"
"""The method Table 7 tests every other against: AMLM-BIPSO."""
PAPER_METHODS = tuple(f"m{i}" for i in range(1, 10))
PAPER_TABLE6: dict[str, dict[str, float]] = {
    "before": {"rmse": 2.177, "mae": 2.006, "max": 3.99},
    "m1": {"seconds": 89.635},
    "m2": {"seconds": 87.512},
    "m3": {"seconds": 140.216},
    "m4": {"seconds": 92.147},
    "m5": {"seconds": 120.643},
    "m6": {"seconds": 106.215},
    "m7": {"rmse": 0.372, "mae": 0.306, "max": 0.911, "seconds": 92.156},
    "m8": {"seconds": 160.258},
    "m9": {"rmse": 0.332, "mae": 0.272, "max": 0.840},
}
"""What the paper reports on the real robot (mm; times in the paper's unstated unit, probably
MATLAB seconds). The paper's Table 6 itself is not in the text we have; these are the values its
text quotes (method-notes §3). M9's time is not quoted."""
SIGNIFICANCE = 0.05
TIE_RTOL = 1e-9
"""A paired difference within this fraction of the larger value is a tie (no change): two
methods that reach the same point differ by round-off, which a rank test must not count."""


def alias(method: str) -> str:
    """The paper's label of a method (``m2``), or "" for methods beyond the paper."""
    try:
        return SOLVERS.alias(get_solver(method).name)
    except UnknownChoiceError:
        return ""


def _stats(values: Sequence[float]) -> dict[str, float]:
    array = np.asarray(values, dtype=np.float64)
    return {"mean": float(np.mean(array)), "std": float(np.std(array, ddof=1))
            if array.size > 1 else 0.0, "median": float(np.median(array)),
            "rms": float(np.sqrt(np.mean(array**2))), "n": int(array.size)}


def _by_method(rows: Sequence[TrialRow], methods: Sequence[str]) -> dict[str, list[TrialRow]]:
    grouped: dict[str, list[TrialRow]] = {m: [] for m in methods}
    for row in rows:
        grouped.setdefault(row.method, []).append(row)
    return {m: sorted(g, key=lambda r: r.trial) for m, g in grouped.items() if g}


def table6(rows: Sequence[TrialRow], methods: Sequence[str]) -> dict[str, Any]:
    """Mean ± std over trials of the validation metrics and the time, per method."""
    grouped = _by_method(rows, methods)
    first = next(iter(grouped.values()))
    table: dict[str, Any] = {"before": {
        "rmse": _stats([r.before_rmse_mm for r in first]),
        "mae": _stats([r.before_mae_mm for r in first]),
        "max": _stats([r.before_max_mm for r in first]),
    }}
    for method, group in grouped.items():
        table[method] = {
            "alias": alias(method),
            "rmse": _stats([r.validation_rmse_mm for r in group]),
            "mae": _stats([r.validation_mae_mm for r in group]),
            "std": _stats([r.validation_std_mm for r in group]),
            "max": _stats([r.validation_max_mm for r in group]),
            "train_rmse": _stats([r.train_rmse_mm for r in group]),
            "seconds": _stats([r.seconds for r in group]),
            "iterations": _stats([r.iterations for r in group]),
            "evaluations": _stats([r.evaluations for r in group]),
            "converged": sum(r.converged for r in group) / len(group),
            "stop_reasons": dict(Counter(r.stop_reason for r in group).most_common()),
        }
    return table


def table7(rows: Sequence[TrialRow], methods: Sequence[str]) -> dict[str, Any]:
    """Wilcoxon signed-rank tests of M9 against every other method on validation RMSE."""
    grouped = _by_method(rows, methods)
    by_alias = {alias(m): m for m in grouped}
    missing = [a.upper() for a in PAPER_METHODS if a not in by_alias]
    result: dict[str, Any] = {"reference": by_alias.get(PAPER_REFERENCE), "missing": missing,
                              "tests": {}}
    reference = by_alias.get(PAPER_REFERENCE)
    if reference is None:
        result["note"] = ("M9 (AMLM-BIPSO) is not in this study, so there is no Table 7: "
                          "run with --methods all once M9 is registered.")
        return result
    ref = {r.trial: r.validation_rmse_mm for r in grouped[reference]}
    for method, group in grouped.items():
        if method == reference:
            continue
        other = {r.trial: r.validation_rmse_mm for r in group}
        trials = sorted(set(ref) & set(other))
        mine, theirs = (np.array([rmse[t] for t in trials]) for rmse in (ref, other))
        difference = mine - theirs
        changed = np.abs(difference) > TIE_RTOL * np.maximum(np.abs(mine), np.abs(theirs))
        entry: dict[str, Any] = {"alias": alias(method), "n": len(trials),
                                 "median_difference_mm": float(np.median(difference))}
        if not np.any(changed):
            entry.update(statistic=None, p_value=1.0, verdict="identical RMSE in every trial")
        else:
            # scipy.stats is half a second of a study's start-up: only Table 7 needs it.
            from scipy.stats import wilcoxon

            with warnings.catch_warnings():
                # scipy warns that n < 50 uses the exact distribution or few samples: expected.
                warnings.simplefilter("ignore")
                test = wilcoxon(difference[changed])
            p = float(test.pvalue)
            better = float(np.median(difference)) < 0
            entry.update(statistic=float(test.statistic), p_value=p, verdict=(
                ("M9 lower" if better else "M9 higher")
                + (" (significant)" if p < SIGNIFICANCE else " (not significant)")))
        result["tests"][method] = entry
    if missing:
        result["note"] = ("Not in this study: " + ", ".join(missing)
                          + "; their rows are missing from Table 7.")
    return result


def truth_table(rows: Sequence[TrialRow], methods: Sequence[str]) -> dict[str, Any]:
    """Workspace flange error against the truth, its Cramér–Rao bound and their ratio."""
    return {
        method: {
            "alias": alias(method),
            "flange_error": _stats([r.flange_error_mm for r in group]),
            "crlb": _stats([r.crlb_mm for r in group]),
            "crlb_ratio": _stats([r.crlb_ratio for r in group]),
        }
        for method, group in _by_method(rows, methods).items()
    }


def verdict(t6: Mapping[str, Any], truth: Mapping[str, Any]) -> dict[str, str]:
    """Which method is best by validation RMSE, by flange error against the truth, by time."""
    methods = [m for m in t6 if m != "before"]
    best_rmse = min(methods, key=lambda m: t6[m]["rmse"]["mean"])
    best_truth = min(truth, key=lambda m: truth[m]["flange_error"]["mean"])
    fastest = min(methods, key=lambda m: t6[m]["seconds"]["mean"])
    return {"validation_rmse": best_rmse, "flange_error": best_truth, "time": fastest}


def summarize(rows: Sequence[TrialRow], methods: Sequence[str], cases: Sequence[str],
              context: Mapping[str, Any]) -> dict[str, Any]:
    """The summary document: per case, Table 6, Table 7, the truth table and the verdict."""
    document: dict[str, Any] = {**context, "paper": PAPER_TABLE6, "cases": []}
    for case in cases:
        chosen = [r for r in rows if r.case == case]
        if not chosen:
            continue
        t6, truth = table6(chosen, methods), truth_table(chosen, methods)
        document["cases"].append({
            "case": case, "trials": len({r.trial for r in chosen}),
            "table6": t6, "table7": table7(chosen, methods), "truth": truth,
            "best": verdict(t6, truth),
        })
    return document
