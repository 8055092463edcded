"""Benchmark of the calibration methods M1–M9: wall time, evaluations, and the batched swarm step.

Run by hand: ``.venv/bin/python bench/bench_solvers.py [--repeat 5]``. Data come from the core's
own model (:mod:`twin.synthetic`): the IRB 120 with D-H errors of about 2 mm RMSE on the cable,
120 poses of which 96 train, σ = 0.01 mm. Everything is measured in this one run and printed
side by side:

1. the full M9 run under the paper's protocol (30 AMLM + 30 BIPSO iterations, N = 100
   particles, M = 100 curve points), best and median of ``--repeat`` runs, against the 0.5 s
   target;
2. every method once per repeat under ``--stop`` (default: converge): best wall time,
   iterations, objective evaluations, validation RMSE, its time relative to LM and the stop
   reason;
3. one swarm iteration's evaluation of N + M = 200 candidates on 96 poses: one batched call vs a
   Python loop over the candidates;
4. with ``--large-errors K``: every method on K problems with D-H errors near the bounds
   (uniform ±4 mm / ±4°, 10–25 mm RMSE before calibration), validation RMSE median and max.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np

from twin.calibration.setup import make_problem
from twin.io.robot_file import default_robot
from twin.problem import Problem
from twin.robot import random_poses
from twin.solvers import SOLVERS, get_solver, swarm
from twin.solvers.base import Tracker
from twin.solvers.swarm import N_INTERPOLATED, N_PARTICLES
from twin.stopping import Budget
from twin.synthetic import synthesize
from twin.units import deg_to_rad, m_to_mm, mm_to_m

METHODS = ("ekf", "lm", "pso", "ukf-vslm", "ekf-qibas", "ekf-qpso", "amlm", "bipso", "amlm-bipso")
TARGET_M9_S = 0.5


def paper_problem(seed: int = 0, error_mm: float = 1.5, error_deg: float = 0.2) -> Problem:
    """120 poses (96 train) of an IRB 120 with uniform random D-H errors, σ = 0.01 mm."""
    rng = np.random.default_rng(seed)
    robot = default_robot()
    delta = np.concatenate([rng.uniform(-error_mm, error_mm, 12) * mm_to_m(1.0),
                            rng.uniform(-error_deg, error_deg, 12) * deg_to_rad(1.0)]).reshape(4, 6)
    port_m = mm_to_m([600.0, -400.0, 100.0])
    q = random_poses(robot, 120, rng)
    data = synthesize(robot.perturbed(delta), q, port_m, float(mm_to_m(0.01)), rng)
    return make_problem(robot, data, port_m, seed=seed)[0]


def best_of(repeat: int, run: object) -> list[float]:
    """Wall times of ``repeat`` calls of ``run()``, s."""
    return [timed(run)[0] for _ in range(repeat)]


def timed(run: object) -> tuple[float, float]:
    """(wall, CPU) time of one call of ``run()``, s. On a shared machine the CPU time of this
    process is the better estimate of the time on an idle core."""
    start, start_cpu = time.perf_counter(), time.process_time()
    run()  # type: ignore[operator]
    return time.perf_counter() - start, time.process_time() - start_cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--stop", choices=("converge", "paper"), default="converge",
                        help="stopping protocol of sections 2 and 4 (section 1 is the paper's)")
    parser.add_argument("--large-errors", type=int, default=0, metavar="K",
                        help="also run every method on K problems with errors near the bounds")
    parser.add_argument("--tiny", action="store_true",
                        help="smoke size: one run, small swarms; no figure means anything")
    args = parser.parse_args()
    if args.tiny:
        args.repeat = 1
        swarm.N_PARTICLES = swarm.N_INTERPOLATED = 6
    problem = paper_problem()
    budget = Budget.named(args.stop)
    before = problem.model.residuals(problem.x0, problem.validation)
    print(f"problem: {len(problem.train)} train / {len(problem.validation)} validation poses, "
          f"{problem.model.n_params} unknowns, before: "
          f"{m_to_mm(np.sqrt(np.mean(before**2))):.3f} mm validation RMSE")

    m9 = get_solver("m9")
    wall, cpu = zip(*(timed(lambda: m9.solve(problem, Budget.paper(), np.random.default_rng(0)))
                      for _ in range(args.repeat)), strict=True)
    print(f"\n1. full M9 (30 AMLM + 30 BIPSO, N = {N_PARTICLES}, M = {N_INTERPOLATED}): "
          f"wall best {min(wall):.3f} s, median {statistics.median(wall):.3f} s; "
          f"CPU best {min(cpu):.3f} s (target {TARGET_M9_S} s: CPU best/target = "
          f"{min(cpu) / TARGET_M9_S:.2f}); load average {os.getloadavg()[0]:.1f} "
          f"on {os.cpu_count()} cores")

    print(f"\n2. every method, {args.stop} protocol (best of --repeat runs)")
    print(f"{'method':<12} {'alias':<5} {'time [s]':>9} {'× LM':>8} {'iter':>5} {'evals':>7} "
          f"{'val RMSE [mm]':>14}  stopped by")
    rows = {}
    for name in METHODS:
        solver = get_solver(name)
        results = []

        def run(solver=solver, results=results) -> None:  # type: ignore[no-untyped-def]
            results.append(solver.solve(problem, budget, np.random.default_rng(0)))

        rows[name] = (min(best_of(args.repeat, run)), results[-1])
    lm_time = rows["lm"][0]
    for name, (seconds, result) in rows.items():
        validation = problem.model.residuals(result.x, problem.validation)
        print(f"{name:<12} {SOLVERS.alias(name):<5} {seconds:9.4f} {seconds / lm_time:8.1f} "
              f"{result.iterations:5d} {result.evaluations:7d} "
              f"{m_to_mm(np.sqrt(np.mean(validation**2))):14.5f}  {result.stop_label}")

    candidates = problem.x0 + np.random.default_rng(1).normal(
        0.0, 1e-3, size=(N_PARTICLES + N_INTERPOLATED, problem.model.n_params))
    tracker = Tracker(problem, "bench")
    batched = best_of(args.repeat * 4, lambda: tracker.cost(candidates))
    looped = best_of(args.repeat, lambda: [tracker.cost(x) for x in candidates])
    np.testing.assert_allclose(tracker.cost(candidates),
                               [tracker.cost(x) for x in candidates], rtol=1e-12)
    print(f"\n3. one swarm evaluation, {candidates.shape[0]} candidates × "
          f"{len(problem.train)} poses: batched {min(batched) * 1e3:.2f} ms, "
          f"per-candidate loop {min(looped) * 1e3:.2f} ms, "
          f"loop/batched = {min(looped) / min(batched):.1f}×")
    if args.large_errors:
        large_errors(args.large_errors, budget)


def large_errors(k: int, budget: Budget) -> None:
    """Validation RMSE of every method on k problems with errors of ±4 mm / ±4°."""
    rmse: dict[str, list[float]] = {name: [] for name in METHODS}
    before = []
    for seed in range(100, 100 + k):
        problem = paper_problem(seed, error_mm=4.0, error_deg=4.0)
        before.append(float(m_to_mm(np.sqrt(np.mean(
            problem.model.residuals(problem.x0, problem.validation) ** 2)))))
        for name in METHODS:
            x = get_solver(name).solve(problem, budget, np.random.default_rng(seed)).x
            r = problem.model.residuals(x, problem.validation)
            rmse[name].append(float(m_to_mm(np.sqrt(np.mean(r**2)))))
    print(f"\n4. large errors (±4 mm / ±4°), {budget.protocol} protocol, {k} problems, before: "
          f"{min(before):.1f}–{max(before):.1f} mm validation RMSE")
    print(f"{'method':<12} {'median [mm]':>12} {'max [mm]':>10} {'median/LM':>10}")
    lm_median = statistics.median(rmse["lm"])
    for name, values in rmse.items():
        print(f"{name:<12} {statistics.median(values):12.4f} {max(values):10.4f} "
              f"{statistics.median(values) / lm_median:10.2f}")


if __name__ == "__main__":
    main()
