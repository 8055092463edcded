"""Full-pose targets: where a tool's centre point (TCP) must be, in a work object, and the flange
pose that asks of the arm.

A controller states a target as the TCP's pose in a work object: ABB's ``robtarget`` is
``wobj_T_tcp`` (position in mm, orientation as a unit quaternion, scalar first), with the tool
``tool0_T_tcp`` (``tooldata.tframe``) given in the controller's own flange frame ``tool0`` and the
work object ``base_T_wobj`` (``wobjdata``: user frame, then object frame). The chain is::

    base_T_flange = base_T_wobj · wobj_T_tcp · tool0_T_tcp⁻¹ · flange_T_tool0⁻¹

with ``flange_T_tool0`` the controller's ``tool0`` in twin's flange frame (the last frame of the
robot's table): a constant turn for an ABB arm described by D-H, the identity for a URDF chain
that ends at its ``tool0`` link (:func:`controller_tool0`). The world frame is taken as the
robot's base (a single robot on the floor: ABB's default base frame).

Quaternions are ABB's order, ``(qw, qx, qy, qz)``; rotations of the rest of twin are matrices.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from twin.arrays import Array
from twin.geometry.rigid import quaternion_rotation, rotation_quaternion
from twin.robot import RobotModel

TOOL0_LINK = "tool0"
"""The link a ROS-Industrial URDF names the controller's flange frame (REP 199)."""
TOOL0_AT_ZERO = {"ABB IRB 120": np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])}
"""The orientation of the controller's tool0 in the base frame at the calibration position
(every axis at 0), for the arms whose model files twin ships. The IRB 120's faces forward with
its x axis down, Ry(90°) (quaternion 0.707107, 0, 0.707107, 0): its tool0 sits at the flange
centre turned half a turn about the flange axis from the D-H frame of ``models/irb120.toml``,
whose θ6 is 0 where ABB's is 180° (method-notes §1). ROS-Industrial's ``irb120_3_58`` URDF,
whose ``tool0`` is ABB's (REP 199), has the same frame there (``tests/test_rapid.py``)."""
QUATERNION_TOLERANCE = 1e-4
"""How far from 1 a target's quaternion norm may be (ABB's controllers refuse unnormalised
ones; files written to 6 decimals are some 1e-6 off)."""


def pose_matrices(translation_m: ArrayLike, quaternion_wxyz: ArrayLike) -> Array:
    """Poses from positions (m, 3) in m and unit quaternions (m, 4), scalar first: (m, 4, 4).

    Raises:
        ValueError: for a quaternion whose norm is off 1 by more than
            :data:`QUATERNION_TOLERANCE` (it is normalised otherwise).
    """
    p = np.asarray(translation_m, dtype=np.float64).reshape(-1, 3)
    quaternion = np.asarray(quaternion_wxyz, dtype=np.float64).reshape(-1, 4)
    norm = np.linalg.norm(quaternion, axis=-1)
    if np.any(np.abs(norm - 1.0) > QUATERNION_TOLERANCE):
        raise ValueError(f"quaternion of norm {norm[np.argmax(np.abs(norm - 1.0))]:.6g}, "
                         f"expected a unit quaternion (within {QUATERNION_TOLERANCE:g})")
    poses = np.tile(np.eye(4), (len(p), 1, 1))
    poses[:, :3, :3] = quaternion_rotation(quaternion)
    poses[:, :3, 3] = p
    return poses


def pose_quaternions(poses: ArrayLike, near_wxyz: ArrayLike | None = None) -> tuple[Array, Array]:
    """Positions (m, 3) and unit quaternions (m, 4), scalar first, of poses (m, 4, 4); each
    quaternion's sign is the one nearer ``near_wxyz`` (m, 4) when given (q and −q are the same
    turn: a rewritten target keeps its sign), else with qw ≥ 0."""
    matrices = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)
    quaternion = rotation_quaternion(matrices[:, :3, :3])
    reference = np.tile([1.0, 0.0, 0.0, 0.0], (len(quaternion), 1)) if near_wxyz is None \
        else np.asarray(near_wxyz, dtype=np.float64).reshape(-1, 4)
    flip = np.sum(quaternion * reference, axis=-1) < 0
    quaternion[flip] *= -1.0
    return matrices[:, :3, 3].copy(), quaternion


def flange_targets(wobj_T_tcp: ArrayLike, base_T_wobj: ArrayLike, tool0_T_tcp: ArrayLike,
                   flange_T_tool0: ArrayLike) -> Array:
    """The flange poses (m, 4, 4) that put the TCP at its targets (see the module docstring).

    Args:
        wobj_T_tcp: Targets, shape (m, 4, 4), m.
        base_T_wobj: Each target's work object, shape (m, 4, 4) or (4, 4).
        tool0_T_tcp: Each target's tool, shape (m, 4, 4) or (4, 4).
        flange_T_tool0: The controller's tool0 in twin's flange frame, (4, 4).
    """
    inverse = np.linalg.inv
    return np.asarray(np.asarray(base_T_wobj, dtype=np.float64)
                      @ np.asarray(wobj_T_tcp, dtype=np.float64)
                      @ inverse(np.asarray(tool0_T_tcp, dtype=np.float64))
                      @ inverse(np.asarray(flange_T_tool0, dtype=np.float64)))


def tcp_targets(base_T_flange: ArrayLike, base_T_wobj: ArrayLike, tool0_T_tcp: ArrayLike,
                flange_T_tool0: ArrayLike) -> Array:
    """Inverse of :func:`flange_targets`: the TCP's pose in its work object, (m, 4, 4)."""
    inverse = np.linalg.inv
    return np.asarray(inverse(np.asarray(base_T_wobj, dtype=np.float64))
                      @ np.asarray(base_T_flange, dtype=np.float64)
                      @ np.asarray(flange_T_tool0, dtype=np.float64)
                      @ np.asarray(tool0_T_tcp, dtype=np.float64))


def controller_tool0(robot: RobotModel) -> Array | None:
    """The controller's flange frame ``tool0`` in twin's flange frame, (4, 4), when twin knows
    it: the identity for a robot read from a URDF whose chain ends at ``tool0`` (REP 199: the
    manufacturer's flange frame); for the model files twin ships, the turn from the flange to
    :data:`TOOL0_AT_ZERO` at the calibration position (whatever θ6 the table has); None
    otherwise (the caller must be told)."""
    if robot.urdf is not None:
        return np.eye(4) if robot.urdf.tip_link == TOOL0_LINK else None
    known = TOOL0_AT_ZERO.get(robot.name)
    if known is None:
        return None
    base_T_flange = robot.flange_transforms(np.zeros((1, robot.n_joints)))[0]
    flange_T_tool0 = np.eye(4)
    flange_T_tool0[:3, :3] = base_T_flange[:3, :3].T @ known
    return flange_T_tool0
