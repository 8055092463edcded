"""Run a study: the trials not yet in the folder, on an executor, then tables and figures.

::

    from twin.study.definition import load_study
    from twin.study.runner import run_study
    from twin.study.executors.local import LocalProcesses

    plan = load_study("scenarios/paper_irb120.toml")
    run_study(plan, "out/paper", LocalProcesses())     # writes results.csv, summary.md, PNGs
"""

from __future__ import annotations

import json
import pickle
from collections.abc import Callable, Mapping
from contextlib import closing
from functools import partial
from itertools import chain
from pathlib import Path
from typing import Any, TextIO

from twin.geometry.kinematics import bulk_work
from twin.io.atomic import write_atomic
from twin.io.lock import folder_lock
from twin.study.definition import StudyPlan
from twin.study.executors import Executor, make_batches
from twin.study.figures import write_figures
from twin.study.markdown import summary_markdown
from twin.study.progress import Progress
from twin.study.statistics import summarize
from twin.study.store import StudyStore, TrialOutcome, open_store
from twin.study.trial import TrialSpec, run_batch

LOADING_NOTE_S = 3.0
"""A run's first trial that takes longer than this (0.4 s from numba's cache) is said to be
loading the compiled kernels."""
LOADING_NOTE = ("the first trial loads the compiled kernels; after an install numba compiles "
                "them first, once (about half a minute on 2 cores)")


def run_trials(
    plan: StudyPlan,
    folder: str | Path,
    executor: Executor,
    *,
    stream: TextIO | None = None,
    on_outcome: Callable[[TrialOutcome], None] | None = None,
) -> StudyStore:
    """Run the trials of ``plan`` that ``folder`` does not hold yet, recording each as it ends
    (the caller holds the folder's lock: :func:`run_study`, :func:`twin.study.check.check`).

    Args:
        plan: The study.
        folder: Study folder; trials already recorded there are not run again.
        executor: Where trials run (entered here); for one whose workers are forked from this
            process, the first trial runs here, before they start.
        stream: Where the progress bar goes; stderr by default.
        on_outcome: Called in this process with each newly recorded trial.

    Returns:
        The study folder's store, with every trial of the plan recorded.
    """
    store = open_store(plan, folder)
    finished = store.finished()
    todo = [key for key in plan.keys if key not in finished]
    if not todo:
        return store
    specs = {case.label: TrialSpec(case.scenario, plan.methods, plan.workspace_poses)
             for case in plan.cases}
    with executor:
        progress = Progress(len(plan.keys), len(plan.keys) - len(todo), stream)
        try:
            # Workers forked from here inherit the compiled kernel the first trial loads, when
            # it runs here before they start (measured: each loaded it again, 0.3 s of CPU per
            # worker and 16 % more CPU per trial with two of them), and on the specs as a
            # worker receives them, pickled: an array frozen here comes back writeable, and
            # numba makes a kernel's version per writeable flags of its inputs (each worker
            # loaded four more, 0.2 s of CPU, when this trial ran on these).
            here = todo[:1] if executor.forks else []
            batches = make_batches(todo[len(here):], executor.workers)
            first = []
            if here:
                # On the compiled kernel, as the workers; this process's choice back after it.
                with progress.note_after(LOADING_NOTE_S, LOADING_NOTE), bulk_work():
                    first = [run_batch(pickle.loads(pickle.dumps(specs)), here)]
            # Closed however the loop ends, so that a stop ends the workers' batches here.
            with closing(executor.run(partial(run_batch, specs), batches)) as work:
                for outcomes in chain(first, work):
                    recorded = store.record(outcomes)
                    progress.advance(len(recorded))
                    if on_outcome is not None:
                        for outcome in recorded:
                            on_outcome(outcome)
        finally:
            progress.close()
    return store


def run_study(plan: StudyPlan, folder: str | Path, executor: Executor, *,
              stream: TextIO | None = None,
              on_outcome: Callable[[TrialOutcome], None] | None = None) -> dict[str, Any]:
    """:func:`run_trials`, then the summary and figures, holding the folder's lock
    (:mod:`twin.io.lock`: a second study of the same folder is refused at once); returns the
    summary document."""
    with folder_lock(folder, "twin study"):
        return write_report(plan, run_trials(plan, folder, executor, stream=stream,
                                             on_outcome=on_outcome), stream=stream,
                            executor=executor)


def write_report(plan: StudyPlan, store: StudyStore, *, figures: bool = True,
                 stream: TextIO | None = None, executor: Executor | None = None
                 ) -> dict[str, Any]:
    """Write `summary.md`, `summary.json` and (unless ``figures`` is False) the figures from
    what the folder holds, their progress bar on ``stream`` (stderr by default), drawn on the
    ``executor``'s workers where it forks them (:func:`twin.study.figures.write_figures`)."""
    keys = plan.keys
    labels = [case.label for case in plan.cases]
    context = {"scenario": plan.cases[0].scenario.name, "source": str(plan.source),
               "methods": list(plan.methods), "trials": plan.trials, "seed": plan.seed,
               "workspace_poses": plan.workspace_poses}
    document = summarize(store.rows(keys), plan.methods, labels, context)
    details = store.details(keys)
    by_case = {label: [d for d in details if d["case"] == label] for label in labels}
    document["figures"] = write_figures(store.folder, document, by_case, plan.methods,
                                        stream, executor) if figures else []
    write_summary(store.folder, document)
    return document


def write_summary(folder: str | Path, document: Mapping[str, Any]) -> None:
    """Write the summary document as `summary.json` and, rendered, as `summary.md`."""
    folder = Path(folder)
    write_atomic(folder / "summary.json", json.dumps(document, indent=2) + "\n")
    write_atomic(folder / "summary.md", summary_markdown(document))
