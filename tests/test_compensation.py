"""Error compensation: batched IK on the identified model, and reading identified results."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from twin.cable import Measurements
from twin.calibration import calibrate
from twin.compensation import (
    STATUS_JOINT_LIMIT,
    STATUS_OK,
    STATUS_UNREACHABLE,
    check_compensation,
    compensate_program,
    compensate_targets,
    nominal_ik,
    reachable_targets,
    solve_ik,
)
from twin.errors import InputError
from twin.io.identified import load_result_delta
from twin.io.results import result_to_dict, write_json
from twin.kinematics import flange_jacobian, flange_position, flange_transform
from twin.robot import RobotModel
from twin.uncertainty import flange_error_rms


def test_flange_jacobian_matches_finite_differences(true_robot: RobotModel) -> None:
    """The geometric Jacobian's columns equal central differences of position and rotation."""
    rng = np.random.default_rng(3)
    q = rng.uniform(true_robot.lower_rad, true_robot.upper_rad, (20, true_robot.n_joints))
    base_T_flange, jacobian = flange_jacobian(true_robot.dh, q)
    np.testing.assert_allclose(base_T_flange, flange_transform(true_robot.dh, q), atol=1e-15)
    step = 1e-6
    for i in range(true_robot.n_joints):
        dq = np.zeros(true_robot.n_joints)
        dq[i] = step
        plus = flange_transform(true_robot.dh, q + dq)
        minus = flange_transform(true_robot.dh, q - dq)
        linear = (plus[:, :3, 3] - minus[:, :3, 3]) / (2 * step)
        # dR/dq · Rᵀ = [ω]×: read ω off the skew-symmetric part.
        skew = (plus[:, :3, :3] - minus[:, :3, :3]) / (2 * step) @ np.swapaxes(
            base_T_flange[:, :3, :3], -1, -2)
        angular = np.stack([skew[:, 2, 1], skew[:, 0, 2], skew[:, 1, 0]], axis=-1)
        np.testing.assert_allclose(jacobian[:, :3, i], linear, atol=1e-8)
        np.testing.assert_allclose(jacobian[:, 3:, i], angular, atol=1e-8)


def test_program_compensation_reaches_nominal_pose(
    irb120: RobotModel, true_robot: RobotModel
) -> None:
    """Corrected program joints put the identified flange at the nominal pose (1e-10 m / rad)."""
    rng = np.random.default_rng(0)
    q, _ = reachable_targets(irb120, 500, rng)
    solved = compensate_program(irb120, true_robot, q)
    assert np.all(solved.status == STATUS_OK)
    reached, wanted = flange_transform(true_robot.dh, solved.q_rad), flange_transform(irb120.dh, q)
    np.testing.assert_allclose(reached[:, :3, 3], wanted[:, :3, 3], atol=2e-10)
    np.testing.assert_allclose(reached[:, :3, :3], wanted[:, :3, :3], atol=2e-10)
    # Millimetre-sized table errors need corrections of a few degrees at most near the wrist,
    # not a jump to another IK branch (which differs by radians).
    assert np.max(np.abs(solved.q_rad - q)) < 0.2


def test_target_compensation_is_minimum_norm(irb120: RobotModel, true_robot: RobotModel) -> None:
    """Position-only compensation reaches the targets with the smallest joint change."""
    rng = np.random.default_rng(1)
    q, target = reachable_targets(irb120, 300, rng)
    solved = compensate_targets(true_robot, target, q)
    assert np.all(solved.ok)
    np.testing.assert_allclose(flange_position(true_robot.dh, solved.q_rad), target, atol=2e-10)
    # The change lies in the row space of the position Jacobian (the minimum-norm solution's
    # first-order condition); its component in the null space is second order.
    _, jacobian = flange_jacobian(true_robot.dh, solved.q_rad)
    change = solved.q_rad - q
    _, _, vt = np.linalg.svd(jacobian[:, :3, :])
    null_part = np.einsum("mkj,mj->mk", vt[:, 3:, :], change)
    assert np.max(np.linalg.norm(null_part, axis=-1) / np.linalg.norm(change, axis=-1)) < 0.05


def test_nominal_ik_finds_in_limit_solutions(irb120: RobotModel) -> None:
    """Multi-start nominal IK solves every reachable target within the joint limits."""
    rng = np.random.default_rng(2)
    _, target = reachable_targets(irb120, 200, rng)
    solved = nominal_ik(irb120, target, np.random.default_rng(5))
    assert np.all(solved.ok)
    np.testing.assert_allclose(flange_position(irb120.dh, solved.q_rad), target, atol=2e-10)
    assert np.all(solved.q_rad >= irb120.lower_rad) and np.all(solved.q_rad <= irb120.upper_rad)


def test_unreachable_and_out_of_limits_are_flagged(irb120: RobotModel) -> None:
    """A target beyond reach is unreachable; a solution past a limit is flagged, not clipped."""
    far = np.array([[2.0, 0.0, 0.3]])
    assert nominal_ik(irb120, far, np.random.default_rng(0)).status.tolist() == [
        STATUS_UNREACHABLE
    ]
    # Joint 3 at its upper limit: the same pose with q3 a little beyond needs no limit change
    # in the table, only a target that the chain reaches past the limit.
    q = np.array([[0.2, 0.3, irb120.upper_rad[2] + 0.01, 0.4, 0.5, 0.6]])
    target = flange_position(irb120.dh, q)
    solved = solve_ik(irb120, target, q - np.array([0, 0, 0.02, 0, 0, 0]))
    assert solved.status.tolist() == [STATUS_JOINT_LIMIT]
    assert solved.q_rad[0, 2] > irb120.upper_rad[2]


def test_compensation_with_identified_model_reaches_identification_accuracy(
    irb120: RobotModel, true_robot: RobotModel, measurements: Measurements, port_m: np.ndarray
) -> None:
    """After LM on core-made data, compensated targets miss by the identified model's own
    flange error (hundredths of a mm), against millimetres uncompensated."""
    result = calibrate(irb120, measurements, port_m, method="lm", seed=0)
    identified = result.identified_robot
    rng = np.random.default_rng(11)
    q, target = reachable_targets(irb120, 1000, rng)
    solved = compensate_targets(identified, target, q)
    check = check_compensation(
        target, flange_position(true_robot.dh, q), flange_position(true_robot.dh, solved.q_rad),
        solved,
    )
    assert check.n_failed == 0
    assert check.nominal.rmse > 1e-3
    floor = flange_error_rms(identified.dh, true_robot.dh, q)
    assert check.compensated.rmse < 3 * floor
    assert check.compensated.rmse < 0.1 * check.nominal.rmse


def test_load_result_delta_single_and_all(
    tmp_path: Path, irb120: RobotModel, measurements: Measurements, port_m: np.ndarray
) -> None:
    """A result file round-trips its delta; a multi-method file needs --method and names them."""
    result = calibrate(irb120, measurements, port_m, method="lm", seed=0)
    single, multi = tmp_path / "one.json", tmp_path / "all.json"
    write_json(single, result_to_dict(result))
    write_json(multi, {"methods": {"lm": result_to_dict(result)}})
    np.testing.assert_allclose(load_result_delta(single, 6), result.delta, atol=1e-15)
    np.testing.assert_allclose(load_result_delta(multi, 6, "lm"), result.delta, atol=1e-15)
    with pytest.raises(InputError, match="lm"):
        load_result_delta(multi, 6)
    with pytest.raises(InputError, match="one of lm"):
        load_result_delta(multi, 6, "pso")
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"delta": {"a": [0.0] * 5}}))
    with pytest.raises(InputError, match=r"bad\.json: delta"):
        load_result_delta(bad, 6)
