"""The Pinocchio bridge agrees with the core's forward kinematics."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from twin.pinocchio_bridge import FLANGE_FRAME, build_model, robot_to_urdf
from twin.robot import RobotModel, default_robot

N_POSES = 1000


def _perturbed_robot(seed: int) -> RobotModel:
    """The IRB 120 with D-H errors of a few mm / degrees, so no entry is special."""
    rng = np.random.default_rng(seed)
    robot = default_robot()
    scale = np.repeat([3e-3, 3e-3, np.deg2rad(3.0), np.deg2rad(3.0)], robot.n_joints)
    return robot.perturbed(rng.uniform(-1.0, 1.0, 4 * robot.n_joints) * scale)


def _random_poses(robot: RobotModel, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform(robot.lower_rad, robot.upper_rad, (N_POSES, robot.n_joints))


def _pinocchio_flange(model: pin.Model, q_rad: np.ndarray) -> np.ndarray:
    """base_T_flange from Pinocchio for each pose, shape (m, 4, 4)."""
    data = model.createData()
    frame = model.getFrameId(FLANGE_FRAME)
    poses = []
    for q in q_rad:
        pin.framesForwardKinematics(model, data, q)
        poses.append(data.oMf[frame].homogeneous.copy())
    return np.array(poses)


def _assert_same_poses(ours: np.ndarray, theirs: np.ndarray) -> None:
    np.testing.assert_allclose(theirs[:, :3, 3], ours[:, :3, 3], rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(theirs[:, :3, :3], ours[:, :3, :3], rtol=0.0, atol=1e-9)


@pytest.mark.parametrize("seed", [0, 1])
def test_build_model_flange_matches_core(seed: int) -> None:
    """Pinocchio's flange frame equals flange_transform to 1e-9 m and 1e-9 on 1000 poses."""
    robot = default_robot() if seed == 0 else _perturbed_robot(seed)
    q = _random_poses(robot, seed)
    _assert_same_poses(robot.flange_transforms(q), _pinocchio_flange(build_model(robot), q))


def test_build_model_carries_limits() -> None:
    """The Pinocchio model has one revolute joint per D-H row and the robot's limits."""
    robot = default_robot()
    model = build_model(robot)
    assert model.nq == robot.n_joints
    np.testing.assert_array_equal(model.lowerPositionLimit, robot.lower_rad)
    np.testing.assert_array_equal(model.upperPositionLimit, robot.upper_rad)


def test_urdf_loads_in_pinocchio_and_matches_core() -> None:
    """The URDF text loads in Pinocchio and its `flange` frame equals the core's FK."""
    robot = _perturbed_robot(7)
    model = pin.buildModelFromXML(robot_to_urdf(robot))
    assert model.nq == robot.n_joints
    q = _random_poses(robot, 7)
    _assert_same_poses(robot.flange_transforms(q), _pinocchio_flange(model, q))
    np.testing.assert_allclose(model.lowerPositionLimit, robot.lower_rad, rtol=0, atol=1e-15)
