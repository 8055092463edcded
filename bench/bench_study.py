"""Benchmark of `twin study`: the paper replica end to end, and scaling over Dask workers.

Run by hand: ``.venv/bin/python bench/bench_study.py [--trials 200] [--skip-replica]``.

1. The paper replica (scenarios/paper_irb120.toml: 10 trials × 120 poses × every registered
   method) end to end on local processes, one per core: wall time against the 30 s target,
   and where the time goes (simulation, each method).
2. 200 trials of the geometric scenario with LM on a Dask LocalCluster of 1 and of 2 workers,
   and on local processes: wall time of the trials (start-up and shut-down measured apart and
   subtracted) and the scaling efficiency T1 / (2 · T2).
"""

from __future__ import annotations

import argparse
import io
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from twin.sim.simulate import simulate
from twin.study.definition import load_study
from twin.study.executors.cluster import DaskCluster
from twin.study.executors.local import LocalProcesses
from twin.study.runner import run_study, run_trials
from twin.study.trial import trial_seed

ROOT = Path(__file__).resolve().parent.parent
PAPER = ROOT / "scenarios" / "paper_irb120.toml"
GEOMETRIC = ROOT / "scenarios" / "geometric_irb120.toml"
TARGET_S = 30.0


def replica(folder: Path, tiny: bool = False) -> None:
    """Time the paper replica end to end and break the time down (``tiny``: one trial, LM)."""
    plan = load_study(PAPER, trials=1, methods=["lm"]) if tiny else load_study(PAPER)
    start = time.perf_counter()
    document = run_study(plan, folder, LocalProcesses(), stream=io.StringIO())
    wall = time.perf_counter() - start
    scenario = plan.cases[0].scenario
    simulate(scenario, trial_seed(scenario.seed, plan.trials))  # loads what a first one loads
    start = time.perf_counter()
    for trial in range(plan.trials):
        simulate(scenario, trial_seed(scenario.seed, trial))
    simulation = (time.perf_counter() - start) / plan.trials
    table = document["cases"][0]["table6"]
    per_method = {m: table[m]["seconds"]["mean"] for m in plan.methods}
    cpu = sum(per_method.values()) + simulation
    print(f"paper replica: {plan.trials} trials × {scenario.pose_count} poses × "
          f"{len(plan.methods)} methods on {os.cpu_count()} cores")
    print(f"  wall time end to end      {wall:8.1f} s   (target {TARGET_S:.0f} s: "
          f"{wall / TARGET_S:.2f}× the target)")
    print(f"  per trial: simulation     {simulation:8.3f} s")
    for method, seconds in sorted(per_method.items(), key=lambda item: -item[1]):
        print(f"  per trial: {method:<14} {seconds:8.3f} s   ({seconds / cpu:5.1%})")
    print(f"  per trial, all work       {cpu:8.3f} s   -> ideal wall on {os.cpu_count()} cores "
          f"{cpu * plan.trials / (os.cpu_count() or 1):.1f} s")


def scaling(folder: Path, trials: int) -> None:
    """Wall time of ``trials`` LM trials on 1 and 2 Dask workers and on local processes.

    Each executor's start-up and shut-down, measured with no work, is subtracted and shown.
    """
    plan = load_study(GEOMETRIC, trials=trials, methods=["lm"])
    times: dict[str, float] = {}
    for label, make in (("dask, 1 worker", lambda: DaskCluster(workers=1)),
                        ("dask, 2 workers", lambda: DaskCluster(workers=2)),
                        ("local, 1 process", lambda: LocalProcesses(1)),
                        ("local, 2 processes", lambda: LocalProcesses(2))):
        start = time.perf_counter()
        with make():
            pass
        overhead = time.perf_counter() - start
        start = time.perf_counter()
        run_trials(plan, folder / label.replace(" ", "_").replace(",", ""), make(),
                   stream=io.StringIO())
        times[label] = time.perf_counter() - start - overhead
        print(f"  {label:<20} start + stop {overhead:5.1f} s, {trials} trials "
              f"{times[label]:7.1f} s ({times[label] / trials * 1e3:6.1f} ms per trial)")
    for kind, one, two in (("dask", times["dask, 1 worker"], times["dask, 2 workers"]),
                           ("local", times["local, 1 process"], times["local, 2 processes"])):
        print(f"  {kind}: speed-up 1 -> 2 workers {one / two:.2f}×, scaling efficiency "
              f"T1 / (2·T2) = {one / (2 * two):.0%}")
    ratio = times["dask, 2 workers"] / times["local, 2 processes"]
    print(f"  dask(2) / local(2) wall = {ratio:.2f}"
          f"; load average (1 min) now {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores "
          "(other work on the machine takes cores from the workers)")
    rows = np.loadtxt(folder / "dask_2_workers" / "results.csv", delimiter=",", skiprows=1,
                      usecols=0)
    assert sorted(rows.astype(int).tolist()) == list(range(trials)), "a trial counted twice"


def main() -> None:
    """Run the benchmarks and print the measured figures."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--trials", type=int, default=200, help="trials of the scaling run")
    parser.add_argument("--skip-replica", action="store_true")
    parser.add_argument("--tiny", action="store_true",
                        help="smoke size: 1 replica trial with LM, 2 scaling trials; no figure "
                        "means anything")
    args = parser.parse_args()
    if args.tiny:
        args.trials = 2
    with tempfile.TemporaryDirectory() as temporary:
        folder = Path(temporary)
        if not args.skip_replica:
            replica(folder / "paper", tiny=args.tiny)
        print(f"scaling: {args.trials} trials of {GEOMETRIC.name} with LM; load average "
              f"(1 min) before {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
        scaling(folder, args.trials)


if __name__ == "__main__":
    main()
