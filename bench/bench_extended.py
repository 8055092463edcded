"""An extended fit (D-H + transmission + backlash + compliance) with twin's LM against scipy.

Run by hand: ``python bench/bench_extended.py``. The data are the MuJoCo twin's: the paper's
rig (transmission error, backlash, compliant servos under gravity and a 5 N cable, 0.01 mm
repeatability, 0.004 mm encoder) with the link masses and centres of mass 20 % off the robot
file's, 400 poses split 320 / 80. Both solvers fit the same 60 unknowns to the same training
residuals inside the same bounds, from the nominal model:

- twin's LM (analytic Jacobian by the chain rule, :mod:`twin.solvers.lm`), run to convergence;
- ``scipy.optimize.least_squares``, trust-region reflective, finite-difference Jacobian
  (``2-point``), tolerances tightened to :data:`SCIPY_TOL` so that it reaches the same cost.

Prints the median wall time of repeated runs, taken in turns (twin, scipy, twin, …) so that a
machine shared with other work slows both alike, the ratio measured side by side in this run,
and each final cost, checked equal: apart by less than :data:`COST_NOISE_SHARE` of one
residual's noise variance σ̂² = cost / (m − p), far below what any validation could tell apart.
(scipy's finite differences, steps of about 1e-8, limit how close it gets: some 1e-5 of the
cost.) The poses' cached bases (compliance torques, harmonics) are computed before the clocks
start, for both.

BLAS runs on one thread unless the environment says otherwise (:data:`BLAS_THREADS`): on a
machine whose cores are busy with other work, multi-threaded BLAS waits for its threads, and
scipy's larger products and SVDs suffer far more from it than twin's: within a few minutes the
same scipy run (43 Jacobians) took from 0.74 to 2.2 s and the ratio swung from 29× to 91×. On
one thread scipy is as fast here (0.70–0.78 s), and both sides pay for the load alike.
"""
# ruff: noqa: E402 — the imports follow the BLAS threads' setting

from __future__ import annotations

import os

BLAS_THREADS = {name: os.environ.setdefault(name, "1") for name in (
    "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}
"""Threads of the BLAS libraries, set before numpy loads them (module docstring)."""

import statistics
import time
import tomllib
from collections.abc import Callable
from pathlib import Path

import numpy as np
from _timing import median_time, tiny_run
from scipy.optimize import least_squares

from twin.calibration.settings import CalibrationSettings
from twin.calibration.setup import make_problem
from twin.rig import Rig
from twin.scenario import parse_scenario
from twin.sim import simulate
from twin.solvers.lm import SOLVER as LM
from twin.stopping import Budget

ROOT = Path(__file__).resolve().parents[1]
ERRORS = ("dh", "transmission", "backlash", "compliance")
REPEATS = 5
"""Timed runs of each solver."""
COST_NOISE_SHARE = 0.01
"""Final costs apart by less than this share of σ̂² count as equal."""
SCIPY_TOL = 1e-9
"""scipy's ftol, xtol and gtol: the loosest of 1e-8 … 1e-12 at which TRF reaches the same cost
on every run (2e-3 σ̂² apart, 38–44 Jacobians). With its defaults (1e-8) it stops 0.006–0.011 σ̂²
above, not reliably equal. Tighter it gains nothing the criterion can see but creeps on along
the directions the data barely see (d2 − d3, joint 6's compliance) for as long as round-off lets
it: at 1e-12, 43 Jacobians with two BLAS threads and 108 with one, on the same data."""


def timed_in_turns(runs: dict[str, Callable[[], np.ndarray]], repeats: int
                   ) -> dict[str, tuple[float, np.ndarray]]:
    """Median wall time of ``repeats`` runs of each, the runs taken in turns, and each one's
    last solution."""
    times: dict[str, list[float]] = {name: [] for name in runs}
    solutions = {name: np.empty(0) for name in runs}
    for _ in range(repeats):
        for name, run in runs.items():
            start = time.perf_counter()
            solutions[name] = run()
            times[name].append(time.perf_counter() - start)
    return {name: (statistics.median(times[name]), solutions[name]) for name in runs}


def main() -> None:
    global REPEATS
    tiny = tiny_run(__doc__)
    if tiny:
        REPEATS = 1
    path = ROOT / "scenarios" / "paper_irb120.toml"
    document = tomllib.loads(path.read_text(encoding="utf-8"))
    document["poses"]["count"] = 100 if tiny else 400
    document["physics"]["mass_error"] = 0.2
    scenario = parse_scenario(document, path)
    sim = simulate(scenario)
    rig = Rig.cable(sim.port_nominal_m, tension_n=scenario.physics.tension_n)
    problem = make_problem(sim.robot, sim.measurements, rig=rig, seed=sim.seed,
                           settings=CalibrationSettings(errors=ERRORS)).problem
    model, train = problem.model, problem.train
    lower, upper = problem.lower, problem.upper

    def residuals(x: np.ndarray) -> np.ndarray:
        return model.residuals(x, train)

    jacobians: dict[str, int] = {}

    def twin_lm() -> np.ndarray:
        solved = LM.solve(problem, Budget(), np.random.default_rng(0))
        jacobians["twin lm"] = solved.evaluations
        return solved.x

    def scipy_trf() -> np.ndarray:
        solved = least_squares(residuals, problem.x0, jac="2-point", bounds=(lower, upper),
                               method="trf", ftol=SCIPY_TOL, xtol=SCIPY_TOL, gtol=SCIPY_TOL)
        jacobians["scipy trf, 2-point J"] = int(solved.njev)
        return np.asarray(solved.x)

    model.jacobian(problem.x0, train)  # fills the poses' cached bases, for both
    runs = {"twin lm": twin_lm, "scipy trf, 2-point J": scipy_trf}
    results = timed_in_turns(runs, REPEATS)
    one_residual, _ = median_time(lambda: residuals(problem.x0), 50)
    one_jacobian, _ = median_time(lambda: model.jacobian(problem.x0, train), 50)
    print(f"{len(train)} training poses, {model.n_params} unknowns ({', '.join(ERRORS)}); "
          f"{scenario.name} rig, masses 20 % off, seed {sim.seed}")
    print(f"{'solver':<24}{'runs':>6}{'Jacobians':>11}{'median time [s]':>17}"
          f"{'final cost [mm²]':>19}{'time / twin lm':>16}")
    reference = results["twin lm"][0]
    costs = {}
    for name, (seconds, x) in results.items():
        costs[name] = float(np.sum(residuals(x) ** 2)) * 1e6
        print(f"{name:<24}{REPEATS:>6}{jacobians[name]:>11}{seconds:>17.3f}"
              f"{costs[name]:>19.6e}{seconds / reference:>16.1f}")
    variance = costs["twin lm"] / (len(train) - model.n_params)
    apart = abs(costs["scipy trf, 2-point J"] - costs["twin lm"]) / variance
    verdict = "equal" if apart < COST_NOISE_SHARE else "NOT equal"
    print(f"\ntwin lm is {results['scipy trf, 2-point J'][0] / reference:.0f}x faster than "
          f"least_squares(method='trf', jac='2-point'); final costs {verdict}: apart by "
          f"{apart:.1e} σ̂² (threshold {COST_NOISE_SHARE:g} σ̂², σ̂² = {variance:.2e} mm²).")
    print(f"One residual evaluation takes {one_residual * 1e3:.2f} ms and one analytic Jacobian "
          f"{one_jacobian * 1e3:.2f} ms ({one_jacobian / one_residual:.1f} residuals): a "
          f"difference Jacobian costs {model.n_params + 1} residuals, "
          f"{(model.n_params + 1) * one_residual / one_jacobian:.0f}x an analytic one.")


if __name__ == "__main__":
    main()
