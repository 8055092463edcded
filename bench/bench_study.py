"""Benchmark of `twin study`: the paper replica end to end.

Run by hand: ``.venv/bin/python bench/bench_study.py``.

The paper replica (scenarios/paper_irb120.toml: 10 trials × 120 poses × every registered
method) end to end on local processes, one per core: wall time against the 30 s target, and
where the time goes (simulation, each method). Then its figures drawn again, here and on the
local processes (forked, as `twin study` draws them on Linux), in alternating rounds after one
that pays matplotlib's first use: the wall time of each and their ratio. How trials scale over
local processes and Dask workers is part 5 of bench_speed.py, measured beside its goal.
"""

from __future__ import annotations

import argparse
import io
import os
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from twin.sim.simulate import simulate
from twin.study.definition import StudyPlan, load_study
from twin.study.executors.local import LocalProcesses
from twin.study.figures import write_figures
from twin.study.runner import run_study
from twin.study.store import open_store
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
    figures(folder, plan, document, rounds=1 if tiny else 3)


def figures(folder: Path, plan: StudyPlan, document: dict[str, Any], rounds: int) -> None:
    """The replica's figures drawn here and on the local processes, alternating ``rounds``
    times after a round here that pays matplotlib's first use: median wall time of each."""
    details = open_store(plan, folder).details(plan.keys)
    by_case = {case.label: [d for d in details if d["case"] == case.label]
               for case in plan.cases}
    executor = LocalProcesses()
    ways = {"here": None, f"on {executor.workers} local processes": executor}

    def draw(way: LocalProcesses | None) -> tuple[float, int]:
        start = time.perf_counter()
        names = write_figures(folder, document, by_case, plan.methods, io.StringIO(), way)
        return time.perf_counter() - start, len(names)

    _, count = draw(None)  # matplotlib's first use in this process, paid before the rounds
    times: dict[str, list[float]] = {label: [] for label in ways}
    for _ in range(rounds):
        for label, way in ways.items():
            times[label].append(draw(way)[0])
    here, there = (statistics.median(values) for values in times.values())
    print(f"  figures ({count}), median of {rounds}: drawn here {here:.2f} s, "
          f"{list(ways)[1]} {there:.2f} s ({here / there:.2f}×; forked workers: "
          f"{executor.forks})")


def main() -> None:
    """Run the replica and print the measured figures."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--tiny", action="store_true",
                        help="smoke size: 1 replica trial with LM; no figure means anything")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as temporary:
        replica(Path(temporary) / "paper", tiny=args.tiny)


if __name__ == "__main__":
    main()
