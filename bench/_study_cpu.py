"""Study CPU per trial of the twin found on ``sys.path`` (bench_speed.py runs this script in a
process of its own per commit it compares, the tree of each on PYTHONPATH).

``python _study_cpu.py MODE SIZES SCENARIO``: first one trial that loads and caches what a
first trial loads (imports, the compiled kernel; a trial no run below repeats), so that what is
measured is only what every trial, or every `twin study` run, pays again. Then:

- MODE ``inprocess`` (SIZES one trial count): blocks of trials one after the other in this
  process, as stdin asks for them — a line ``FIRST COUNT`` runs trials FIRST … FIRST + COUNT − 1
  as one batch (``run_batch``, as a worker runs a batch) and prints ``{"cpu_s": …}``, their
  CPU per trial — until stdin closes. Two trees served in
  turn, block by block, see the same drift of a shared machine's speed. A line ``FIRST COUNT
  stages`` (this tree only: it names this tree's functions, :data:`STAGES`) adds
  ``"stages": {label: CPU per trial}``, what each stage of a trial took. A line ``scenario
  PATH`` serves that scenario's trials from then on, after a warm-up trial of its own (trial
  :data:`WARM_TRIAL`), and prints ``{"ready": true}``.
- MODE one or more of ``local1``, ``local2``, ``dask1``, ``dask2``, separated by commas (SIZES
  trial counts separated by commas): for each executor in turn, a run of each size one after
  the other, as `twin study` runs trials, on that many local processes or Dask workers, the
  executor's start and stop included; one JSON line of each executor's runs: their wall times,
  when each trial was recorded and, local processes only, the CPU per trial of this process
  and its workers. Local processes run before Dask's: their workers are forked from here,
  which is safe only before a Dask client has started its threads.

Apart from the stages, only the API that every compared commit has is used.
"""

from __future__ import annotations

import importlib
import io
import json
import resource
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

STAGES = {
    "simulate": [("twin.study.trial", "simulate")],
    "calibrate": [("twin.study.trial", "calibrate_many")],
    "LM": [("twin.solvers.lm", "levenberg_marquardt")],
    "hold": [("twin.calibration.pipeline", "hold_unseen")],
    "identifiability": [("twin.calibration.pipeline", "measurement_identifiability")],
    "bound": [("twin.study.trial", "cramer_rao_rms")],
    "truth": [("twin.study.trial", "trial_truth"), ("twin.study.trial", "truth_errors")],
}
"""A trial's stages, each the functions whose CPU it is, where a trial reaches them: LM, the
hold and the identifiability run inside calibrate."""
WARM_TRIAL = 10_000
"""The warm-up trial of a scenario served after the first (no block reaches it)."""


def _run_cpu() -> float:
    """CPU of this process and its finished workers so far, s."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime + time.process_time()


def _timed(spent: Counter[str]) -> None:
    """Wrap every function of :data:`STAGES` where a trial calls it, adding its CPU to
    ``spent`` under its stage's label."""
    for label, places in STAGES.items():
        for module_name, name in places:
            module = importlib.import_module(module_name)
            setattr(module, name, _timer(getattr(module, name), label, spent))


def _timer(function: Callable[..., Any], label: str, spent: Counter[str]
           ) -> Callable[..., Any]:
    def timed(*args: Any, **kwargs: Any) -> Any:
        start = time.process_time()
        try:
            return function(*args, **kwargs)
        finally:
            spent[label] += time.process_time() - start
    return timed


def _served(plan: Any) -> tuple[dict[str, Any], str]:
    """What a block of the plan's first case runs: the trial specs by case, and its label."""
    from twin.study.trial import TrialSpec

    case = plan.cases[0]
    return {case.label: TrialSpec(case.scenario, plan.methods, plan.workspace_poses)}, case.label


def in_process(plan: Any) -> None:
    """Serve the blocks of trials stdin asks for, printing each block's CPU per trial, s (and
    with ``stages``, each stage's); a ``scenario`` line switches the plan."""
    from twin.study.definition import load_study
    from twin.study.trial import run_batch

    specs, case = _served(plan)
    spent: Counter[str] = Counter()
    wrapped = False
    print(json.dumps({"ready": True}), flush=True)
    for line in sys.stdin:
        words = line.split()
        if words[0] == "scenario":
            specs, case = _served(load_study(Path(words[1]), trials=1, methods=["lm"]))
            run_batch(specs, [(case, WARM_TRIAL)])
            print(json.dumps({"ready": True}), flush=True)
            continue
        first, count, stages = int(words[0]), int(words[1]), words[2:] == ["stages"]
        if stages and not wrapped:
            _timed(spent)
            wrapped = True
        spent.clear()
        start = time.process_time()
        run_batch(specs, [(case, trial) for trial in range(first, first + count)])
        found: dict[str, Any] = {"cpu_s": (time.process_time() - start) / count}
        if stages:
            found["stages"] = {label: spent[label] / count for label in STAGES}
        print(json.dumps(found), flush=True)


def through_executor(plan: Any, trials: int, kind: str, workers: int) -> dict[str, Any]:
    """A run of the trials: its wall time, s; when each trial was recorded, s from the start,
    in order (``done_s``); and (local processes) the CPU per trial of this process and its
    workers, s."""
    from twin.study.runner import run_trials

    if kind == "local":
        from twin.study.executors.local import LocalProcesses

        executor: Any = LocalProcesses(workers)
    else:
        from twin.study.executors.cluster import DaskCluster

        executor = DaskCluster(workers=workers)
    done: list[float] = []
    with tempfile.TemporaryDirectory() as folder:
        cpu, start = _run_cpu(), time.perf_counter()
        run_trials(plan, Path(folder) / "study", executor, stream=io.StringIO(),
                   on_outcome=lambda _: done.append(time.perf_counter() - start))
        found: dict[str, Any] = {"trials": trials, "wall_s": time.perf_counter() - start,
                                 "done_s": done}
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
    """Warm up, then serve blocks of trials (``inprocess``) or run each size and print the
    runs' figures as one JSON line."""
    mode, scenario = sys.argv[1], Path(sys.argv[3])
    sizes = [int(size) for size in sys.argv[2].split(",")]
    from twin.study.definition import load_study

    plans = {size: load_study(scenario, trials=size, methods=["lm"]) for size in set(sizes)}
    warm_up(plans[sizes[0]], max(sizes))
    if mode == "inprocess":
        in_process(plans[sizes[0]])
        return
    executors = sorted(mode.split(","), key=lambda name: name.startswith("dask"))
    runs = {name: [through_executor(plans[size], size, name[:-1], int(name[-1]))
                   for size in sizes] for name in executors}
    print(json.dumps({"runs": runs}))


if __name__ == "__main__":
    main()
