"""LM wall time and final cost: ours vs scipy.optimize.least_squares on the same data.

Run by hand: ``python bench/bench_calibration.py``. 96 training poses of an IRB 120 with a
known ~1.3 mm perturbation and σ = 0.01 mm noise; every solver starts at the nominal model.
Prints the median wall time of repeated runs and the ratios measured in this run; twin's LM
under both stopping protocols (converge, and the paper's 0.001 mm² rule).
"""

from __future__ import annotations

import numpy as np
from _timing import median_time, tiny_run
from scipy.optimize import least_squares

from twin.calibration.setup import make_problem
from twin.io.robot_file import default_robot
from twin.robot import random_poses
from twin.solvers.lm import SOLVER as LM
from twin.stopping import Budget
from twin.synthetic import synthesize
from twin.units import dh_rows_from_display, mm_to_m

REPEATS = 15


def main() -> None:
    global REPEATS
    tiny = tiny_run(__doc__)
    if tiny:
        REPEATS = 1
    robot = default_robot()
    rng = np.random.default_rng(1)
    delta = dh_rows_from_display({
        "a": [0.5, -0.8, 0.6, 0.3, -0.4, 0.2], "d": [0.7, 0.4, -0.6, 0.5, 0.3, -0.5],
        "alpha": [0.1, -0.2, 0.15, -0.1, 0.2, 0.1], "theta": [0.2, 0.1, -0.15, 0.1, -0.2, 0.05],
    })
    port = mm_to_m([600.0, -400.0, 100.0])
    q = random_poses(robot, 40 if tiny else 120, rng)
    data = synthesize(robot.perturbed(delta), q, port, 1e-5, rng)
    problem = make_problem(robot, data, port, seed=0).problem
    model, train = problem.model, problem.train

    def residuals(x: np.ndarray) -> np.ndarray:
        return model.residuals(x, train)

    def jacobian(x: np.ndarray) -> np.ndarray:
        return model.jacobian(x, train)[1]

    runs = {
        "twin lm (--stop paper)": lambda: LM.solve(
            problem, Budget.paper(), np.random.default_rng(0)).x,
        "twin lm (converge)": lambda: LM.solve(
            problem, Budget(), np.random.default_rng(0)).x,
        "scipy lm, numeric J": lambda: least_squares(residuals, problem.x0, method="lm").x,
        "scipy trf, our J": lambda: least_squares(
            residuals, problem.x0, jac=jacobian, method="trf",
            bounds=(problem.lower, problem.upper)).x,
    }
    results = {name: median_time(run, REPEATS) for name, run in runs.items()}
    reference = results["twin lm (converge)"][0]
    print(f"{'solver':<28}{'median time [ms]':>18}{'final f [mm²]':>16}{'time / twin lm':>16}"
          f"{'max |x|/bound':>15}")
    for name, (seconds, x) in results.items():
        f_mm2 = float(np.mean(residuals(x) ** 2)) * 1e6
        print(f"{name:<28}{seconds * 1e3:>18.2f}{f_mm2:>16.3e}{seconds / reference:>16.1f}"
              f"{np.max(np.abs(x) / problem.upper):>15.2f}")
    scipy_lm = results["scipy lm, numeric J"][0]
    print(f"\ntwin lm is {scipy_lm / reference:.1f}x faster than least_squares(method='lm') "
          f"run to convergence, {scipy_lm / results['twin lm (--stop paper)'][0]:.1f}x with "
          "the paper's stopping rule; scipy trf with our Jacobian takes "
          f"{results['scipy trf, our J'][0] / reference:.1f}x the time of twin lm.")
    print("scipy's unbounded lm reaches a lower f only by leaving the ±5 mm / ±8° box along the "
          "near-null d2-d3 direction (max |x|/bound above); inside the box trf and twin lm agree.")


if __name__ == "__main__":
    main()
