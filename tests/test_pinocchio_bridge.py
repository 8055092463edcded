"""The Pinocchio bridge agrees with the core's forward kinematics, for every parametrisation."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from twin.export.pinocchio import FLANGE_FRAME, build_model, urdf_flange
from twin.io.robot_file import default_robot, load_robot
from twin.robot import RobotModel

N_POSES = 1000
MODELS = Path(__file__).resolve().parents[1] / "models"


def _perturbed(robot: RobotModel, seed: int) -> RobotModel:
    """A robot with table errors of a few mm / degrees, so no entry is special."""
    rng = np.random.default_rng(seed)
    scale = np.where(robot.is_length, 3e-3, np.deg2rad(3.0))
    return robot.perturbed(rng.uniform(-1.0, 1.0, scale.shape) * scale)


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


ROBOTS = {
    "irb120": default_robot,
    "irb120 perturbed": lambda: _perturbed(default_robot(), 1),
    "irb120 mdh perturbed": lambda: _perturbed(default_robot().reparametrised("mdh"), 2),
    "ur5e auto perturbed": lambda: _perturbed(load_robot(MODELS / "ur5e" / "ur5e.urdf"), 3),
    "fr3 auto perturbed": lambda: _perturbed(load_robot(MODELS / "fr3" / "fr3.urdf"), 4),
    "fr3 on a torso lift, perturbed": lambda: _perturbed(
        load_robot(MODELS / "fr3_torso" / "fr3_torso.urdf"), 5),
    "fr3 on a torso lift, dh, perturbed": lambda: _perturbed(
        load_robot(MODELS / "fr3_torso" / "fr3_torso.urdf").reparametrised("dh"), 6),
}


@pytest.mark.parametrize("name", list(ROBOTS))
def test_build_model_flange_matches_core(name: str) -> None:
    """Pinocchio's flange frame equals flange_transform to 1e-9 m and 1e-9 on 1000 poses, for
    standard and modified D-H, Hayati joints, base and tool transforms, and a prismatic joint
    (Pinocchio's PZ joint, q in m) in Hayati and standard D-H form."""
    robot = ROBOTS[name]()
    q = _random_poses(robot, 0)
    _assert_same_poses(robot.flange_transforms(q), _pinocchio_flange(build_model(robot), q))


def test_build_model_carries_limits_and_names() -> None:
    """The Pinocchio model has one revolute joint per table column, the robot's limits and
    joint names."""
    robot = load_robot(MODELS / "ur5e" / "ur5e.urdf")
    model = build_model(robot)
    assert model.nq == robot.n_joints
    assert tuple(model.names)[1:] == robot.joint_names
    np.testing.assert_array_equal(model.lowerPositionLimit, robot.lower_rad)
    np.testing.assert_array_equal(model.upperPositionLimit, robot.upper_rad)


def test_urdf_flange_is_pinocchio_of_the_document() -> None:
    """urdf_flange of a URDF equals the bridge's model of the robot read from it."""
    robot = load_robot(MODELS / "ur5e" / "ur5e.urdf")
    assert robot.urdf is not None
    q = _random_poses(robot, 5)[:200]
    found = urdf_flange(robot.urdf.text, robot.joint_names, q, robot.urdf.tip_link,
                        robot.urdf.base_link)
    _assert_same_poses(_pinocchio_flange(build_model(robot), q), found)
