"""A study's tables: the paper's Table 6 and Table 7 replicas and the truth table.

- **Table 6**: mean ± std over trials of each method's validation RMSE, MAE (labelled "STD" as
  in the paper, whose eq. 32 "STD" is a mean absolute error), MAX and time, beside the paper's
  values (method-notes §3) where the paper gives them.
- **Table 7**: Wilcoxon signed-rank test (:func:`scipy.stats.wilcoxon`, two-sided) of M9
  against every other method on the validation RMSE, paired by trial. A method that is not in
  the study is named as missing rather than left out silently.
- **Truth table**: the RMS flange-position error over the workspace against the true geometry,
  its Cramér–Rao bound and their ratio (1 = as good as any unbiased estimator can be).

Every number is in mm or s. The summary is written as `summary.md` and `summary.json`.
"""

from __future__ import annotations

import json
import warnings
from collections import Counter
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from scipy.stats import wilcoxon

from twin.errors import UnknownChoiceError
from twin.io.atomic import write_atomic
from twin.solvers import get_solver

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


def alias(method: str) -> str:
    """The paper's label of a method (``m2``), or "" for methods beyond the paper."""
    try:
        return get_solver(method).alias
    except UnknownChoiceError:
        return ""


def _stats(values: Sequence[float]) -> dict[str, float]:
    array = np.asarray(values, dtype=np.float64)
    return {"mean": float(np.mean(array)), "std": float(np.std(array, ddof=1))
            if array.size > 1 else 0.0, "median": float(np.median(array)), "n": int(array.size)}


def _by_method(rows: Sequence[Mapping[str, Any]], methods: Sequence[str]
               ) -> dict[str, list[Mapping[str, Any]]]:
    grouped: dict[str, list[Mapping[str, Any]]] = {m: [] for m in methods}
    for row in rows:
        grouped.setdefault(row["method"], []).append(row)
    return {m: sorted(g, key=lambda r: r["trial"]) for m, g in grouped.items() if g}


def table6(rows: Sequence[Mapping[str, Any]], methods: Sequence[str]) -> dict[str, Any]:
    """Mean ± std over trials of the validation metrics and the time, per method."""
    grouped = _by_method(rows, methods)
    first = next(iter(grouped.values()))
    table: dict[str, Any] = {"before": {
        key: _stats([r[f"before_{key}_mm"] for r in first]) for key in ("rmse", "mae", "max")}}
    for method, group in grouped.items():
        table[method] = {
            "alias": alias(method),
            **{key: _stats([r[f"validation_{key}_mm"] for r in group])
               for key in ("rmse", "mae", "std", "max")},
            "train_rmse": _stats([r["train_rmse_mm"] for r in group]),
            "seconds": _stats([r["seconds"] for r in group]),
            "iterations": _stats([r["iterations"] for r in group]),
            "evaluations": _stats([r["evaluations"] for r in group]),
            "converged": sum(bool(r["converged"]) for r in group) / len(group),
            "stop_reasons": dict(Counter(r["stop_reason"] for r in group).most_common()),
        }
    return table


def table7(rows: Sequence[Mapping[str, Any]], methods: Sequence[str]) -> dict[str, Any]:
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
    ref = {r["trial"]: r["validation_rmse_mm"] for r in grouped[reference]}
    for method, group in grouped.items():
        if method == reference:
            continue
        other = {r["trial"]: r["validation_rmse_mm"] for r in group}
        trials = sorted(set(ref) & set(other))
        difference = np.array([ref[t] - other[t] for t in trials])
        entry: dict[str, Any] = {"alias": alias(method), "n": len(trials),
                                 "median_difference_mm": float(np.median(difference))}
        if np.all(difference == 0):
            entry.update(statistic=None, p_value=1.0, verdict="identical RMSE in every trial")
        else:
            with warnings.catch_warnings():
                # scipy warns that n < 50 uses the exact distribution or few samples: expected.
                warnings.simplefilter("ignore")
                test = wilcoxon(difference)
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


def truth_table(rows: Sequence[Mapping[str, Any]], methods: Sequence[str]) -> dict[str, Any]:
    """Workspace flange error against the truth, its Cramér–Rao bound and their ratio."""
    return {
        method: {
            "alias": alias(method),
            "flange_error": _stats([r["flange_error_mm"] for r in group]),
            "crlb": _stats([r["crlb_mm"] for r in group]),
            "crlb_ratio": _stats([r["crlb_ratio"] for r in group]),
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


def summarize(rows: Sequence[Mapping[str, Any]], methods: Sequence[str], cases: Sequence[str],
              context: Mapping[str, Any]) -> dict[str, Any]:
    """The summary document: per case, Table 6, Table 7, the truth table and the verdict."""
    document: dict[str, Any] = {**context, "paper": PAPER_TABLE6, "cases": []}
    for case in cases:
        chosen = [r for r in rows if r["case"] == case]
        if not chosen:
            continue
        t6, truth = table6(chosen, methods), truth_table(chosen, methods)
        document["cases"].append({
            "case": case, "trials": len({r["trial"] for r in chosen}),
            "table6": t6, "table7": table7(chosen, methods), "truth": truth,
            "best": verdict(t6, truth),
        })
    return document


def _pm(stats: Mapping[str, float], digits: int = 4) -> str:
    return f"{stats['mean']:.{digits}f} ± {stats['std']:.{digits}f}"


def _paper(method_alias: str, key: str) -> str:
    value = PAPER_TABLE6.get(method_alias, {}).get(key)
    return "" if value is None else f"{value:g}"


def _reasons(counts: Mapping[str, int]) -> str:
    return ", ".join(f"{reason} ×{count}" for reason, count in counts.items())


def _case_markdown(case: Mapping[str, Any]) -> list[str]:
    t6, t7, truth = case["table6"], case["table7"], case["truth"]
    lines = [
        f"### Table 6 replica — validation residuals, {case['trials']} trials (mean ± std)",
        "",
        "| method | paper | RMSE [mm] | STD* [mm] | MAX [mm] | time [s] | iterations | "
        "converged | stopped by | paper RMSE / STD / MAX | paper time |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    before = t6["before"]
    lines.append(f"| before | | {_pm(before['rmse'])} | {_pm(before['mae'])} | "
                 f"{_pm(before['max'])} | | | | | 2.177 / 2.006 / 3.99 | |")
    for method, row in t6.items():
        if method == "before":
            continue
        a = row["alias"]
        paper = " / ".join(_paper(a, k) for k in ("rmse", "mae", "max"))
        lines.append(
            f"| {method} | {a.upper()} | {_pm(row['rmse'])} | {_pm(row['mae'])} | "
            f"{_pm(row['max'])} | {_pm(row['seconds'], 3)} | {row['iterations']['mean']:.1f} | "
            f"{row['converged']:.0%} | {_reasons(row['stop_reasons'])} | "
            f"{paper if paper.strip(' /') else ''} | "
            f"{_paper(a, 'seconds')} |")
    lines += ["", '\\* STD is the paper\'s label; its formula (eq. 32) is the mean absolute '
              "error (MAE). The true standard deviation is in summary.json. The paper's figures "
              "are from the real robot; its times are in an unstated unit (MATLAB).", ""]
    lines += ["### Table 7 replica — Wilcoxon signed-rank test of M9 against each method "
              "(validation RMSE, paired by trial, two-sided)", ""]
    if t7.get("note"):
        lines += [f"**{t7['note']}**", ""]
    if t7["tests"]:
        lines += ["| method | paper | n | median(M9 − method) [mm] | W | p-value | verdict |",
                  "|---|---|---|---|---|---|---|"]
        for method, test in t7["tests"].items():
            statistic = "" if test["statistic"] is None else f"{test['statistic']:g}"
            lines.append(f"| {method} | {test['alias'].upper()} | {test['n']} | "
                         f"{test['median_difference_mm']:+.4f} | {statistic} | "
                         f"{test['p_value']:.4g} | {test['verdict']} |")
        lines.append("")
    lines += ["### Against the truth — RMS flange-position error over the workspace", "",
              "| method | paper | flange error [mm] | Cramér–Rao bound [mm] | ratio (mean) | "
              "ratio (median) |", "|---|---|---|---|---|---|"]
    for method, row in truth.items():
        lines.append(f"| {method} | {row['alias'].upper()} | {_pm(row['flange_error'])} | "
                     f"{row['crlb']['mean']:.4f} | {row['crlb_ratio']['mean']:.2f} | "
                     f"{row['crlb_ratio']['median']:.2f} |")
    best = case["best"]
    lines += ["", f"Best by validation RMSE: **{best['validation_rmse']}**; by flange error "
              f"against the truth: **{best['flange_error']}**; fastest: **{best['time']}**.", ""]
    return lines


def trial_markdown(case: str, trial: int, rows: Sequence[Mapping[str, Any]]) -> str:
    """One trial's results per method as a Markdown table (mm, s)."""
    title = f"Trial {trial}" + (f", {case}" if case else "")
    lines = [f"### {title}", "",
             "| method | validation RMSE [mm] | flange error [mm] | bound ratio | iterations | "
             "time [s] |", "|---|---|---|---|---|---|"]
    for row in rows:
        lines.append(f"| {row['method']} | {row['validation_rmse_mm']:.4f} | "
                     f"{row['flange_error_mm']:.4f} | {row['crlb_ratio']:.2f} | "
                     f"{row['iterations']} | {row['seconds']:.3f} |")
    return "\n".join(lines) + "\n"


def summary_markdown(document: Mapping[str, Any]) -> str:
    """The summary as Markdown."""
    lines = [f"# Study: {document['scenario']}", "",
             f"Methods: {', '.join(document['methods'])}. Trials per case: "
             f"{document['trials']}. Figures: {', '.join(document.get('figures', [])) or 'none'}.",
             ""]
    for case in document["cases"]:
        if case["case"]:
            lines += [f"## Case {case['case']}", ""]
        lines += _case_markdown(case)
    return "\n".join(lines)


def write_summary(folder: str | Path, document: Mapping[str, Any]) -> None:
    """Write `summary.json` and `summary.md` atomically."""
    folder = Path(folder)
    write_atomic(folder / "summary.json", json.dumps(document, indent=2) + "\n")
    write_atomic(folder / "summary.md", summary_markdown(document))
