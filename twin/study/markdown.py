"""A study's summary as Markdown: the tables of :mod:`twin.study.statistics` for `summary.md`,
and one trial's table for a live Rerun report. Numbers in mm and s."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from twin.report.display import (
    DURATION_DECIMALS,
    LENGTH_DECIMALS,
    RATIO_DECIMALS,
    percent,
    plain,
)
from twin.study.rows import TrialRow
from twin.study.statistics import PAPER_TABLE6


def _pm(stats: Mapping[str, float], decimals: int = LENGTH_DECIMALS) -> str:
    return f"{plain(stats['mean'], decimals)} ± {plain(stats['std'], decimals)}"


def _paper(method_alias: str, key: str) -> str:
    value = PAPER_TABLE6.get(method_alias, {}).get(key)
    return "" if value is None else plain(value)


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
            f"{percent(row['converged'], 0)} | {_reasons(row['stop_reasons'])} | "
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
                         f"{plain(test['median_difference_mm'], LENGTH_DECIMALS, sign=True)} | "
                         f"{statistic} | "
                         f"{test['p_value']:.4g} | {test['verdict']} |")
        lines.append("")
    lines += ["### Against the truth — RMS flange-position error over the workspace", "",
              "| method | paper | flange error [mm] | Cramér–Rao bound [mm] | ratio (median) | "
              "ratio (RMS over trials) |", "|---|---|---|---|---|---|"]
    for method, row in truth.items():
        lines.append(f"| {method} | {row['alias'].upper()} | {_pm(row['flange_error'])} | "
                     f"{plain(row['crlb']['mean'], LENGTH_DECIMALS)} | "
                     f"{row['crlb_ratio']['median']:.2f} | {row['crlb_ratio']['rms']:.2f} |")
    best = case["best"]
    lines += ["", f"Best by validation RMSE: **{best['validation_rmse']}**; by flange error "
              f"against the truth: **{best['flange_error']}**; fastest: **{best['time']}**.", ""]
    return lines


def trial_markdown(case: str, trial: int, rows: Sequence[TrialRow]) -> str:
    """One trial's results per method as a Markdown table (mm, s)."""
    title = f"Trial {trial}" + (f", {case}" if case else "")
    lines = [f"### {title}", "",
             "| method | validation RMSE [mm] | flange error [mm] | bound ratio | iterations | "
             "time [s] |", "|---|---|---|---|---|---|"]
    for row in rows:
        lines.append(f"| {row.method} | {plain(row.validation_rmse_mm, LENGTH_DECIMALS)} | "
                     f"{plain(row.flange_error_mm, LENGTH_DECIMALS)} | "
                     f"{plain(row.crlb_ratio, RATIO_DECIMALS)} | {row.iterations} | "
                     f"{plain(row.seconds, DURATION_DECIMALS)} |")
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
