"""Errors near the search bounds: the LM family reaches the bounded least-squares optimum.

The regime that exposed LM's old clipping bug (D-H errors uniform within ±4 mm on a, d and ±6°
on α, θ; the box is ±5 mm / ±8°): LM ended far from the optimum and said it had converged. The
referee is :func:`scipy.optimize.least_squares` (TRF, our residual and Jacobian, the same box,
the same start), run inside the test; the data come from the MuJoCo twin.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares, lsq_linear

from twin.analysis.uncertainty import cramer_rao_flange_rms, rms_distance
from twin.calibration.setup import make_problem
from twin.geometry import kinematics
from twin.robot import random_poses
from twin.scenario import parse_scenario
from twin.sim import Simulation, simulate
from twin.solvers import get_solver
from twin.solvers.lm import BOX_RTOL, boxed_damped_step, damping
from twin.stopping import Budget

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


@pytest.mark.parametrize("kernel", ["numpy", "numba"], indirect=True)
@pytest.mark.parametrize("seed", range(40))
def test_box_step_is_the_bounded_least_squares_minimiser(seed: int, kernel: str) -> None:
    """LM's step on the box (BVLS on the damped normal equations; numpy's, and the compiled
    one a study's workers take) is the minimiser scipy's BVLS finds on the augmented
    least-squares problem [J; √(μD)] h ≈ [−r; 0], on problems with columns scaled over eleven
    decades, several bounds in the way and some at zero."""
    rng = np.random.default_rng(seed)
    m, p = int(rng.integers(10, 80)), int(rng.integers(2, 40))
    J = rng.normal(size=(m, p)) * np.exp(rng.uniform(-18.0, 7.0, size=p))
    r = rng.normal(size=m) * 10.0 ** rng.uniform(-6, 0)
    damped = damping(J.T @ J, 10.0 ** rng.uniform(-12, -1))
    width = 10.0 ** rng.uniform(-5, -1, size=p)
    low, high = -width * rng.uniform(0, 1, size=p), width * rng.uniform(0, 1, size=p)
    low[rng.uniform(size=p) < 0.1] = 0.0
    step = boxed_damped_step(J.T @ J, J.T @ r, damped, low, high)
    augmented = np.vstack([J, np.diag(np.sqrt(damped))])
    reference = lsq_linear(augmented, np.concatenate([-r, np.zeros(p)]),
                           bounds=(low, np.maximum(high, low + 1e-300)), method="bvls",
                           tol=1e-15).x

    def objective(h: np.ndarray) -> float:
        return float(np.sum((r + J @ h) ** 2) + damped @ (h * h))

    assert np.all((step >= low) & (step <= high))
    decrease = objective(np.zeros(p)) - objective(reference)
    assert objective(step) <= objective(reference) + 1e-9 * decrease
    # Compared in each unknown's own scale (√ of its damped curvature): with columns eleven
    # decades apart the damped system's condition reaches 1e12, and both solvers' steps are
    # then determined only to ~1e-4 along the weak columns, where the objective cannot tell.
    scale = np.sqrt(np.diag(J.T @ J) + damped)
    assert np.max(np.abs(scale * (step - reference))) <= 1e-8 * np.max(np.abs(scale * reference))


@pytest.mark.parametrize("seed", range(20))
def test_the_compiled_box_step_takes_the_numpy_steps(seed: int,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """The compiled BVLS finds the numpy one's step to round-off, on well-scaled problems with
    bounds in the way."""
    pytest.importorskip("numba")
    from twin.solvers.compiled import box_step

    rng = np.random.default_rng(seed)
    m, p = int(rng.integers(20, 80)), int(rng.integers(2, 30))
    J = rng.normal(size=(m, p))
    r = rng.normal(size=m)
    damped = damping(J.T @ J, 10.0 ** rng.uniform(-6, -1))
    width = 10.0 ** rng.uniform(-3, -1, size=p)
    low, high = -width * rng.uniform(0, 1, size=p), width * rng.uniform(0, 1, size=p)
    monkeypatch.setenv(kinematics.KERNEL_VARIABLE, "numpy")
    kinematics._compiled.cache_clear()
    reference = boxed_damped_step(J.T @ J, J.T @ r, damped, low, high)
    A = J.T @ J + np.diag(damped)
    step = box_step(A, J.T @ r, low, high, BOX_RTOL)
    held = np.minimum(reference - low, high - reference) < 1e-12 * width
    assert held.any(), "no bound in the way: the test would not test the box"
    np.testing.assert_allclose(step, reference, rtol=1e-9, atol=1e-12 * float(np.max(width)))
