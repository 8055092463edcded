"""`twin study`: Monte-Carlo trials of a scenario, every method on each trial's same data."""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from twin.choices import MAX_TRIALS, PROTOCOLS
from twin.cli.arguments import (
    add_output,
    add_scenario,
    integer,
)
from twin.errors import InputError
from twin.io.paths import STUDY_FOLDER
from twin.solvers import SOLVERS
from twin.study.executors import Executor, open_executor
from twin.study.executors.cluster import reach_scheduler
from twin.viz.options import add_rerun_flags

if TYPE_CHECKING:
    from twin.study.definition import StudyPlan

TRIAL_REPORT = "study/trial"
"""Rerun entity of each trial's table, on the ``case`` and ``trial`` timelines."""

MAX_WORKERS = 1024


def add_study_arguments(parser: argparse.ArgumentParser,
                        scenario_help: str = "scenario file, with an optional [study] table"
                        ) -> None:
    """The scenario, the study folder, trials, methods, the stopping protocol and where trials
    run (also `twin check`)."""
    add_scenario(parser, scenario_help)
    add_output(parser, "DIR", "study folder (created; resumed if it holds this study)",
               folder=STUDY_FOLDER)
    parser.add_argument("--trials", type=integer(1, MAX_TRIALS), metavar="N",
                        help="trials per case (default: [study] trials, else 10)")
    parser.add_argument("--methods", metavar="M1,M2,…|all",
                        help="comma-separated names or aliases, or 'all' (default: [study] "
                        "methods, else all): " + ", ".join(SOLVERS.choices()))
    parser.add_argument("--stop", choices=PROTOCOLS,
                        help="stopping protocol of every method (default: the scenario's "
                        "[calibration] stop, else converge); part of the study's identity")
    parser.add_argument("--no-figures", dest="figures", action="store_false",
                        help="write the summary but not the PNG figures (faster, for CI); "
                        "`twin study` of the same DIR without it draws them later, running "
                        "no trial")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--workers", type=integer(1, MAX_WORKERS), metavar="K",
                       help="run on a Dask LocalCluster of K worker processes on 127.0.0.1 "
                       "(default: local processes, one per core)")
    where.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                       help="run on the Dask cluster of this scheduler (workers need twin)")


def methods_from_args(args: argparse.Namespace) -> list[str] | None:
    """The names given with ``--methods``, or None."""
    if args.methods is None:
        return None
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    if not methods:
        raise InputError(f"{args.methods!r}", "comma-separated method names, or all",
                         source="--methods")
    return methods


def executor_from_args(args: argparse.Namespace) -> Executor:
    """A Dask cluster with ``--workers``/``--scheduler`` (a scheduler that cannot be reached is
    an input error, raised before anything is written), else local processes."""
    if args.scheduler:
        reach_scheduler(args.scheduler)
    return open_executor(args.scheduler, args.workers)


NAME = "study"
HELP = "Monte-Carlo study of a scenario: every method on the same seeded trials"
DESCRIPTION = (
    "Simulate N seeded trials of SCENARIO (perturbation, poses, noise), run every "
    "method on each trial's same data and split, append the results to DIR/results.csv as "
    "trials finish, then write DIR/summary.md, DIR/summary.json (the paper's Tables 6 and 7 "
    "and the errors against the truth) and PNG figures. Running again with the same DIR "
    "resumes. See docs/studies.md."
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The subcommand's arguments."""
    add_study_arguments(parser)
    add_rerun_flags(parser)


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    from twin.io.lock import folder_lock
    from twin.study.definition import load_study

    executor = executor_from_args(args)
    plan = load_study(args.scenario, trials=args.trials, methods=methods_from_args(args),
                      stop=args.stop)
    # The lock before the first line: a second writer's refusal is its one line.
    with folder_lock(args.out, "twin study"):
        return _run_locked(args, plan, executor)


def _run_locked(args: argparse.Namespace, plan: StudyPlan, executor: Executor) -> int:
    from twin.study.store import TrialOutcome, open_store

    open_store(plan, args.out)  # a folder of another study is refused before the banner
    print(f"twin study: {plan.cases[0].scenario.name}, {len(plan.cases)} case(s) × "
          f"{plan.trials} trials × {len(plan.methods)} methods ({', '.join(plan.methods)}) "
          f"-> {args.out}", file=sys.stderr)
    # What runs the trials loads after the banner (0.3 s of the 0.45 s it took to appear).
    from twin.study.markdown import summary_markdown, trial_markdown
    from twin.study.runner import run_trials, write_report
    from twin.viz.commands import open_from_args

    cases = {case.label: index for index, case in enumerate(plan.cases)}
    with open_from_args(args, "study", fallback_dir=args.out) as recording:
        on_outcome = None
        if recording is not None:
            def on_outcome(outcome: TrialOutcome) -> None:
                recording.log_report(
                    trial_markdown(outcome.case, outcome.trial, outcome.rows), path=TRIAL_REPORT,
                    times={"case": cases[outcome.case], "trial": outcome.trial})
                label = f"{outcome.case}-{outcome.trial}" if outcome.case else str(outcome.trial)
                recording.log_histories({method: detail["history_mm"] for method, detail
                                         in outcome.detail["methods"].items()}, label)

        document = write_report(plan, run_trials(plan, args.out, executor,
                                                 on_outcome=on_outcome), figures=args.figures,
                                executor=executor)
        markdown = summary_markdown(document)
        if recording is not None:
            recording.log_report(markdown)
    print(markdown)
    print(f"written: {args.out / 'results.csv'}, "
          + ", ".join(["summary.md", "summary.json", *document["figures"]]), file=sys.stderr)
    return 0
