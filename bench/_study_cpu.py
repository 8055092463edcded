"""Study CPU per trial of the twin found on ``sys.path`` (bench_speed.py runs this script once
per commit it compares, the tree of each on PYTHONPATH): one JSON line on stdout.

``python _study_cpu.py MODE TRIALS SCENARIO`` where MODE is ``inprocess`` (the trials run one
after the other in this process: CPU per trial, after one that loads and caches what a first
trial loads) or ``local1``, ``local2``, ``dask1``, ``dask2`` (the trials run as `twin study`
runs them, on that many local processes or Dask workers: the CPU per trial of this process
and its workers, local processes only, and the wall time of the run, the executor's start and
stop apart). Only the API that every compared commit has is used.
"""

from __future__ import annotations

import io
import json
import resource
import sys
import tempfile
import time
from pathlib import Path
from typing import Any


def _run_cpu() -> float:
    """CPU of this process and its finished workers so far, s."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime + time.process_time()


def in_process(plan: Any, trials: int) -> dict[str, float]:
    """CPU per trial of trials run in this process, s."""
    from twin.study.trial import TrialSpec, run_trial, workspace

    case = plan.cases[0]
    spec = TrialSpec(case.scenario, plan.methods, plan.workspace_poses)
    space = workspace(spec)
    run_trial(spec, case.label, trials, space)  # imports and caches
    start = time.process_time()
    for trial in range(trials):
        run_trial(spec, case.label, trial, space)
    return {"cpu_s": (time.process_time() - start) / trials}


def through_executor(plan: Any, trials: int, kind: str, workers: int) -> dict[str, float]:
    """The CPU per trial of this process and its workers (local processes) and the wall time of
    the trials, s."""
    from twin.study.runner import run_trials

    if kind == "local":
        from twin.study.executors.local import LocalProcesses

        def make() -> Any:
            return LocalProcesses(workers)
    else:
        from twin.study.executors.cluster import DaskCluster

        def make() -> Any:
            return DaskCluster(workers=workers)
    start = time.perf_counter()
    with make():
        pass
    overhead = time.perf_counter() - start
    with tempfile.TemporaryDirectory() as folder:
        cpu, start = _run_cpu(), time.perf_counter()
        run_trials(plan, Path(folder) / "study", make(), stream=io.StringIO())
        wall = time.perf_counter() - start - overhead
    found = {"wall_s": wall, "overhead_s": overhead}
    if kind == "local":
        found["cpu_s"] = (_run_cpu() - cpu) / trials
    return found


def main() -> None:
    """Run the mode asked for and print its figures as one JSON line."""
    mode, trials, scenario = sys.argv[1], int(sys.argv[2]), Path(sys.argv[3])
    from twin.study.definition import load_study

    plan = load_study(scenario, trials=trials, methods=["lm"])
    if mode == "inprocess":
        try:  # the compiled kernel a study's workers take, where the commit has one
            from twin.geometry.kinematics import for_bulk_work
        except ImportError:
            pass
        else:
            for_bulk_work()
        found = in_process(plan, trials)
    else:
        found = through_executor(plan, trials, mode[:-1], int(mode[-1]))
    print(json.dumps(found))


if __name__ == "__main__":
    main()
