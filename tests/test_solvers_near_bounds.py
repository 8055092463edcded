"""Errors near the search bounds: the LM family reaches the bounded least-squares optimum.

The regime that exposed LM's old clipping bug (D-H errors uniform within ±4 mm on a, d and ±6°
on α, θ; the box is ±5 mm / ±8°): LM ended far from the optimum and said it had converged. The
referee is :func:`scipy.optimize.least_squares` (TRF, our residual and Jacobian, the same box,
the same start), run inside the test; the data come from the MuJoCo twin.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from twin.calibration import make_problem
from twin.scenario import parse_scenario
from twin.sim import Simulation, simulate
from twin.solvers import get_solver
from twin.stopping import Budget
from twin.synthetic import random_poses
from twin.uncertainty import cramer_rao_flange_rms, rms_distance

SEEDS = range(10)
METHODS = ("lm", "amlm", "amlm-bipso")
REGIME = {
    "name": "near_bounds", "seed": 0,
    "port": {"position_mm": [600.0, -400.0, 100.0]},
    "perturbation": {"distribution": "uniform", "a_mm": 4.0, "d_mm": 4.0, "alpha_deg": 6.0,
                     "theta_deg": 6.0},
    "poses": {"count": 120},
    "encoder": {"range_mm": [100.0, 1500.0], "sigma_mm": 0.01, "resolution_mm": 0.004},
}


@pytest.fixture(scope="module")
def simulations(tmp_path_factory: pytest.TempPathFactory) -> list[Simulation]:
    scenario = parse_scenario(REGIME, tmp_path_factory.mktemp("near") / "near_bounds.toml")
    return [simulate(scenario, seed) for seed in SEEDS]


@pytest.mark.parametrize("index", range(len(SEEDS)))
def test_lm_family_matches_scipy_near_the_bounds(simulations: list[Simulation], index: int
                                                 ) -> None:
    """On every draw LM, AMLM and M9 end within 1.5× of scipy's flange error over the
    workspace, at no higher cost, each stopped by a convergence test."""
    sim = simulations[index]
    problem = make_problem(sim.robot, sim.measurements, sim.port_nominal_m, seed=index).problem
    model, train = problem.model, problem.train
    reference = least_squares(
        lambda x: model.residuals(x, train), problem.x0,
        jac=lambda x: model.jacobian(x, train)[1], bounds=(problem.lower, problem.upper),
        method="trf", x_scale="jac",
    )
    workspace = random_poses(sim.robot, 500, np.random.default_rng(1))
    true_flange = sim.true_robot.flange_positions(workspace)
    at_workspace = model.poses(workspace)
    reference_error = rms_distance(model.flange_positions(reference.x, at_workspace),
                                   true_flange)
    sigma_m = float(np.hypot(1e-5, 4e-6 / np.sqrt(12)))
    bound = cramer_rao_flange_rms(model, sim.delta.ravel(), train, sigma_m, workspace)
    assert reference_error < 2.0 * bound  # the referee itself reaches the bound here
    for method in METHODS:
        result = get_solver(method).solve(problem, Budget(), np.random.default_rng(index))
        error = rms_distance(model.flange_positions(result.x, at_workspace), true_flange)
        cost = np.mean(model.residuals(result.x, train) ** 2)
        assert error < 1.5 * reference_error, (method, error / bound, reference_error / bound)
        assert cost <= np.mean(reference.fun**2) * (1 + 1e-6), method
        assert result.converged, (method, result.stop_label)
