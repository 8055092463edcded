"""LM calibration end to end on data with a known perturbation."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.optimize import least_squares

from twin.analysis.uncertainty import cramer_rao_flange_rms, rms_distance
from twin.calibration import hold
from twin.calibration.pipeline import calibrate, calibrate_many
from twin.calibration.result import CalibrationResult
from twin.calibration.settings import CalibrationSettings
from twin.calibration.split import required_poses, split_rows
from twin.dataset import Measurements
from twin.errors import InputError
from twin.problem import Problem
from twin.robot import RobotModel, random_poses
from twin.scenario import load_scenario
from twin.sim import simulate
from twin.synthetic import synthesize


def test_split_is_reproducible_and_disjoint() -> None:
    """The 80/20 split depends only on the seed and covers every row once."""
    train, validation = split_rows(120, seed=5)
    assert train.size == 96 and validation.size == 24
    assert np.array_equal(np.sort(np.r_[train, validation]), np.arange(120))
    again = split_rows(120, seed=5)
    assert np.array_equal(train, again[0]) and not np.array_equal(train, split_rows(120, 6)[0])


def test_lm_recovers_flange_positions_within_twice_the_cramer_rao_bound(
    irb120: RobotModel, true_robot: RobotModel, measurements: Measurements, port_m: np.ndarray,
    true_delta: np.ndarray,
) -> None:
    """σ = 0.01 mm, 96 training poses: the identified model's flange error over 1000 workspace
    poses is within 2× the Cramér–Rao bound computed from the true Jacobian (~0.01 mm)."""
    result = calibrate(irb120, measurements, port_m, method="lm", seed=0)
    workspace = random_poses(irb120, 1000, np.random.default_rng(11))
    error = rms_distance(result.identified_geometry.flange_positions(workspace),
                         true_robot.flange_positions(workspace))
    bound = cramer_rao_flange_rms(
        result.model, true_delta.ravel(), measurements.subset(result.train_rows), 1e-5, workspace
    )
    before = rms_distance(irb120.flange_positions(workspace),
                          true_robot.flange_positions(workspace))
    assert 0.003e-3 < bound < 0.03e-3
    assert error < 2 * bound, (error, bound)
    assert before > 100 * error
    assert result.metrics["validation"].rmse < 1.5e-5 < result.metrics["before"].rmse / 50
    assert result.solver.converged and result.solver.iterations <= 60


def test_history_starts_at_nominal_and_decreases(
    irb120: RobotModel, measurements: Measurements, port_m: np.ndarray
) -> None:
    """History entry 0 is the nominal model; accepted iterations never increase f."""
    result = calibrate(irb120, measurements, port_m, seed=1)
    f = np.array([record.f_m2 for record in result.solver.history])
    assert result.solver.history[0].iteration == 0
    assert f[0] == pytest.approx(result.model.residuals(np.zeros(24), measurements.subset(
        result.train_rows)).__pow__(2).mean())
    assert np.all(np.diff(f) <= 0)


def test_same_seed_same_result(
    irb120: RobotModel, measurements: Measurements, port_m: np.ndarray
) -> None:
    """Calibrating twice with the same seed gives identical numbers."""
    a = calibrate(irb120, measurements, port_m, seed=3)
    b = calibrate(irb120, measurements, port_m, seed=3)
    np.testing.assert_array_equal(a.solver.x, b.solver.x)


def test_noise_free_data_fits_exactly(
    irb120: RobotModel, true_robot: RobotModel, port_m: np.ndarray
) -> None:
    """Without noise and without the paper's loose f-change rule, LM drives the residual to
    numerical zero (the paper's 0.001 mm² rule alone stops at a few µm); with no noise every
    direction the poses see at the truth is seen, and holding the others changes nothing."""
    rng = np.random.default_rng(9)
    data = synthesize(true_robot, random_poses(irb120, 60, rng), port_m, 0.0, rng)
    result = calibrate(irb120, data, port_m, settings=CalibrationSettings())
    assert result.metrics["validation"].rmse < 1e-10
    assert result.held is not None and result.held.f_before_m2 < 1e-20


def test_too_few_poses(irb120: RobotModel, measurements: Measurements, port_m: np.ndarray) -> None:
    """Fewer poses than unknowns need is a clear error, not a silent bad fit."""
    assert required_poses(24) == 30
    with pytest.raises(InputError, match="found 29 poses, expected at least 30"):
        calibrate(irb120, measurements.subset(np.arange(29)), port_m)


def test_lm_reaches_the_bounded_optimum_when_the_truth_is_outside_the_box(
    irb120: RobotModel, port_m: np.ndarray
) -> None:
    """δa2 = 6 mm lies outside the ±5 mm box: LM must end on the bound at the same cost as
    scipy's bounded trf, not stop where the first clipped step fails to descend."""
    rng = np.random.default_rng(12)
    delta = np.zeros((4, 6))
    delta[0, 1], delta[1, 0], delta[3, 2] = 6e-3, -2e-3, np.deg2rad(1.0)
    data = synthesize(irb120.perturbed(delta), random_poses(irb120, 80, rng), port_m, 1e-5, rng)
    result = calibrate(irb120, data, port_m, settings=CalibrationSettings())
    train = data.subset(result.train_rows)
    model = result.model
    reference = least_squares(
        lambda x: model.residuals(x, train), np.zeros(24),
        jac=lambda x: model.jacobian(x, train)[1], bounds=model.bounds(), method="trf",
    )
    assert result.delta[0, 1] == pytest.approx(5e-3, abs=1e-12)
    held = result.held
    assert held is not None and result.identifiability is not None
    assert held.f_before_m2 <= np.mean(reference.fun**2) * 1.01
    # The truth outside the box is a misfit; holding what its noise estimate cannot see costs
    # at most a noise variance per held direction: Δf / f <= k / (m − rank).
    assert result.unseen is not None
    held_directions, dof = len(result.unseen.names), len(train) - result.identifiability.rank
    f = np.mean(model.residuals(result.solver.x, train) ** 2)
    assert f <= held.f_before_m2 * (1 + held_directions / dof)


def test_the_polish_stops_once_a_seen_step_restores_nothing_more(
    irb120: RobotModel, measurements: Measurements, port_m: np.ndarray,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Holding moves the residuals along the unseen directions too, which no step within the
    seen ones takes back: each polish stops once its next step could restore no more than
    POLISH_RTOL of the residuals, not after POLISH_ITERATIONS steps that change nothing; one
    more Gauss–Newton step from where it stopped restores no more than that."""
    polishes: list[tuple[Problem, np.ndarray, np.ndarray, np.ndarray, int]] = []
    polish = hold._polish

    def counted(problem: Problem, x: np.ndarray, target: np.ndarray, seen_x: np.ndarray
                ) -> np.ndarray:
        steps = 0
        jacobian = problem.data_jacobian

        def counting(at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            nonlocal steps
            steps += 1
            return jacobian(at)

        object.__setattr__(problem, "data_jacobian", counting)
        try:
            done = polish(problem, x, target, seen_x)
        finally:
            object.__delattr__(problem, "data_jacobian")
        polishes.append((problem, done, target, seen_x, steps))
        return done

    monkeypatch.setattr(hold, "_polish", counted)
    calibrate(irb120, measurements, port_m, seed=0)
    assert polishes
    assert sum(steps for *_, steps in polishes) < hold.POLISH_ITERATIONS * len(polishes)
    for problem, x, target, seen_x, _ in polishes:
        residuals, jacobian = problem.data_jacobian(x)
        gap = residuals - target
        step = hold._seen_step(jacobian, gap, x, seen_x, problem.lower, problem.upper)
        further = problem.data_residuals(np.clip(x + step, problem.lower, problem.upper))
        restored = np.linalg.norm(gap) - np.linalg.norm(further - target)
        assert restored <= 2 * hold.POLISH_RTOL * np.linalg.norm(target), restored


def test_the_hold_stops_at_its_tolerance_not_at_round_off(monkeypatch: pytest.MonkeyPatch
                                                          ) -> None:
    """A fixture's fixed points trade the unseen directions nonlinearly: holding turns them, and
    the look at the held point finds ~1e-8 of the box left along the turned ones. Each hold
    stops after that one look (within HOLD_ATOL), where a tolerance at round-off took a second
    round for every answer; and its answer is the one holding to round-off reaches (1e-12, the
    referee), to HOLD_ATOL in the hold's weighted units."""
    scenario = load_scenario(Path(__file__).resolve().parents[1] / "scenarios"
                             / "fixed_points_irb120.toml")
    sim = simulate(scenario, 5)
    looks: list[int] = []
    look, one_hold = hold._unseen, hold._hold

    def counted(*args: Any) -> Any:
        looks[-1] += 1
        return look(*args)

    def each(*args: Any) -> Any:
        looks.append(0)
        return one_hold(*args)

    def solved() -> CalibrationResult:
        return calibrate(sim.robot, sim.measurements, rig=sim.rig_told_pulled,
                         settings=scenario.calibration, seed=5)

    monkeypatch.setattr(hold, "_unseen", counted)
    monkeypatch.setattr(hold, "_hold", each)
    result = solved()
    assert looks and set(looks) == {1}, looks
    tolerance = hold.HOLD_ATOL
    monkeypatch.setattr(hold, "HOLD_ATOL", 1e-12)
    looks.clear()
    exact = solved()
    assert max(looks) > 1, looks  # the referee did hold again
    assert result.unseen is not None
    weighted = (result.solver.x - exact.solver.x) / result.unseen.scale
    assert 0 < np.max(np.abs(weighted)) <= tolerance, weighted


def test_on_result_sees_each_method_as_it_finishes(
    irb120: RobotModel, measurements: Measurements, port_m: np.ndarray
) -> None:
    """calibrate_many hands each method's result to on_result (what the live Rerun log uses),
    in the order given, and returns the very same objects."""
    seen: list[CalibrationResult] = []
    results = calibrate_many(irb120, measurements, port_m, ["m7", "lm"], on_result=seen.append)
    assert [result.method for result in seen] == ["amlm", "lm"] == list(results)
    assert all(result is results[result.method] for result in seen)


@pytest.mark.slow
def test_a_result_without_the_report_has_the_same_answer(
    irb120: RobotModel, measurements: Measurements, port_m: np.ndarray
) -> None:
    """report=False (a study's trial) gives each method the same answer, metrics, hold and
    identifiability as a full calibration, and leaves out the checks a report shows."""
    full = calibrate_many(irb120, measurements, port_m, ["lm", "pso"], seed=4)
    lean = calibrate_many(irb120, measurements, port_m, ["lm", "pso"], seed=4, report=False)
    for name, result in full.items():
        bare = lean[name]
        np.testing.assert_array_equal(bare.solver.x, result.solver.x)
        np.testing.assert_array_equal(bare.held.method_x, result.held.method_x)  # type: ignore
        assert bare.metrics == result.metrics
        for found, full_found in ((bare.identified_identifiability,
                                   result.identified_identifiability),
                                  (bare.unseen, result.unseen)):
            assert found is not None and full_found is not None
            for part, full_part in zip(found, full_found, strict=True):
                np.testing.assert_array_equal(part, full_part)
        assert result.uncertainty is not None and result.gauge is not None
        assert (bare.uncertainty, bare.gauge, bare.misfit, bare.workspace, bare.steps) == \
            (None, None, None, None, ())
