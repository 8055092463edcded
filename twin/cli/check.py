"""`twin check`: a study held to its expectations against the truth; exit 1 when one fails."""

from __future__ import annotations

import argparse
import math
import sys

from twin.choices import DEFAULT_TOLERANCE, MAX_TOLERANCE
from twin.cli.study import add_study_arguments, executor_from_args, methods_from_args
from twin.errors import InputError
from twin.io.paths import InputPath, OutputFile

EXIT_FAILED = 1


def _tolerance(text: str) -> float:
    """``5%`` or ``0.05``; a bare number of 1 or more is refused as ambiguous."""
    percent = text.strip().endswith("%")
    try:
        value = float(text.strip().rstrip("%"))
    except ValueError:
        value = math.nan
    if percent:
        value /= 100.0
    if not 0 <= value <= MAX_TOLERANCE or (not percent and value >= 1):
        raise argparse.ArgumentTypeError(f"found {text!r}, expected a relative tolerance from "
                                         f"0 to {MAX_TOLERANCE:.0%}, such as 5% or 0.05")
    return value


NAME = "check"
HELP = "regression test against the truth: a study held to the scenario's [expect] table"
DESCRIPTION = (
    "Run (or resume) the study of SCENARIO into DIR exactly as `twin study` does, "
    "then evaluate every expectation of its [expect] table (or of --expect FILE), e.g. "
    "lm = [\"flange_error_mm p95 <= 0.03\"]: one line per expectation and a total line. "
    "With --baseline, compare every metric the expectations name with an earlier study of "
    "the same seeds, trial by trial (one-sided Wilcoxon signed-rank). Exit code 0 when all "
    "pass, 1 when one fails or regressed, 2 on a user error. See docs/studies.md, Checks."
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The subcommand's arguments."""
    add_study_arguments(parser, "scenario file, with an [expect] table (unless --expect) and "
                        "an optional [study] table")
    parser.add_argument("--expect", type=InputPath, metavar="FILE.toml",
                        help="expectations file with an [expect] table; replaces the scenario's")
    parser.add_argument("--junit", type=OutputFile, metavar="FILE.xml",
                        help="also write the results as JUnit XML, for CI test reports")
    parser.add_argument("--baseline", type=InputPath, metavar="DIR",
                        help="an earlier study of the same scenario seed to compare with")
    parser.add_argument("--tolerance", type=_tolerance, metavar="5%",
                        help="relative worsening a significant change may have without being "
                        "a regression (default 5%%)")


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    from twin.testing import check, write_junit

    if args.tolerance is not None and args.baseline is None:
        raise InputError("--tolerance without --baseline", "it beside --baseline DIR (it says how "
                         "much worse than the baseline a metric may be)", source="--tolerance")
    tolerance = DEFAULT_TOLERANCE if args.tolerance is None else args.tolerance
    if args.baseline is not None and args.out.exists() and args.baseline.exists() \
            and args.out.samefile(args.baseline):
        raise InputError("the --out folder itself", "an earlier study in another folder "
                         "(the check would compare the study with itself)", source="--baseline")
    report = check(args.scenario, args.out, trials=args.trials, methods=methods_from_args(args),
                   expect=args.expect, baseline=args.baseline, tolerance=tolerance,
                   executor=executor_from_args(args), figures=args.figures)
    print(report.text, end="")
    written = [str(args.out / "results.csv"), "summary.md"]
    if args.junit is not None:
        write_junit(args.junit, report)
        written.append(str(args.junit))
    print("written: " + ", ".join(written), file=sys.stderr)
    return 0 if report.passed else EXIT_FAILED
