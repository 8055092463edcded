"""Study CPU per trial of the twin found on ``sys.path`` (bench_speed.py runs this script in a
process of its own per commit it compares, the tree of each on PYTHONPATH): one JSON line on
stdout.

``python _study_cpu.py MODE SIZES SCENARIO``, SIZES trial counts separated by commas, run one
after the other in this process after one trial that loads and caches what a first trial loads
(imports, the compiled kernel), so that each run pays only what every `twin study` run pays
again. MODE is ``inprocess`` (the trials run one after the other here: CPU per trial, first
size only) or ``local1``, ``local2``, ``dask1``, ``dask2`` (each run as `twin study` runs
trials, on that many local processes or Dask workers, the executor's start and stop included:
its wall time and, local processes only, the CPU per trial of this process and its workers).
Only the API that every compared commit has is used.
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
    start = time.process_time()
    for trial in range(trials):
        run_trial(spec, case.label, trial, space)
    return {"cpu_s": (time.process_time() - start) / trials}


def through_executor(plan: Any, trials: int, kind: str, workers: int) -> dict[str, float]:
    """The wall time of a run of the trials, s, and (local processes) the CPU per trial of this
    process and its workers, s."""
    from twin.study.runner import run_trials

    if kind == "local":
        from twin.study.executors.local import LocalProcesses

        executor: Any = LocalProcesses(workers)
    else:
        from twin.study.executors.cluster import DaskCluster

        executor = DaskCluster(workers=workers)
    with tempfile.TemporaryDirectory() as folder:
        cpu, start = _run_cpu(), time.perf_counter()
        run_trials(plan, Path(folder) / "study", executor, stream=io.StringIO())
        found = {"trials": trials, "wall_s": time.perf_counter() - start}
    if kind == "local":
        found["cpu_s"] = (_run_cpu() - cpu) / trials
    return found


def warm_up(plan: Any, trial: int) -> None:
    """Run one trial here as a worker runs it (a trial no run below repeats): its imports and
    the compiled kernel, where the commit has one, are loaded before anything is measured."""
    from twin.study.trial import TrialSpec, run_batch

    case = plan.cases[0]
    run_batch({case.label: TrialSpec(case.scenario, plan.methods, plan.workspace_poses)},
              [(case.label, trial)])


def main() -> None:
    """Run the mode asked for at each size and print the figures as one JSON line."""
    mode, scenario = sys.argv[1], Path(sys.argv[3])
    sizes = [int(size) for size in sys.argv[2].split(",")]
    from twin.study.definition import load_study

    plans = {size: load_study(scenario, trials=size, methods=["lm"]) for size in set(sizes)}
    warm_up(plans[sizes[0]], max(sizes))
    if mode == "inprocess":
        print(json.dumps(in_process(plans[sizes[0]], sizes[0])))
        return
    runs = [through_executor(plans[size], size, mode[:-1], int(mode[-1])) for size in sizes]
    print(json.dumps({"runs": runs}))


if __name__ == "__main__":
    main()
