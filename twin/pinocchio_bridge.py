"""Pinocchio bridge: a :class:`~twin.robot.RobotModel` as a ``pinocchio.Model`` or as URDF text.

An adapter: it imports Pinocchio, and nothing in the core imports it.

Standard D-H places joint i's z axis at the end of link i−1, so joint i's placement in its
parent is the previous link's ``Tz(d_{i−1}) · Tx(a_{i−1}) · Rx(α_{i−1})`` followed by the
constant offset ``Rz(θ_i)``; the joint itself is a revolute about z. The last link's transform
``Tz(d_n) · Tx(a_n) · Rx(α_n)`` becomes the placement of a frame named ``flange`` on joint n.
"""

from __future__ import annotations

import math
from xml.sax.saxutils import quoteattr

import numpy as np
import pinocchio as pin

from twin.robot import RobotModel

FLANGE_FRAME = "flange"
"""Name of the flange frame in the Pinocchio model, the URDF and the MJCF."""


def _rot_x(angle_rad: float) -> np.ndarray:
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rot_z(angle_rad: float) -> np.ndarray:
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _link(robot: RobotModel, i: int) -> pin.SE3:
    """Link i's fixed transform ``Tz(d_i) · Tx(a_i) · Rx(α_i)`` (i from 0)."""
    a, d, alpha, _ = robot.dh[:, i]
    return pin.SE3(_rot_x(float(alpha)), np.array([float(a), 0.0, float(d)]))


def build_model(robot: RobotModel) -> pin.Model:
    """The robot as a Pinocchio model: n revolute-z joints and a ``flange`` frame.

    Joint limits are the robot's; ``model.lowerPositionLimit`` etc. are in rad. Link inertias are
    left empty: the model is for kinematics.

    Args:
        robot: The D-H robot, SI.

    Returns:
        A ``pinocchio.Model`` with ``nq = robot.n_joints`` whose configuration is q in rad, the
        same q as :func:`twin.kinematics.flange_transform` takes.
    """
    if not robot.structure.is_standard:
        raise ValueError(f"{robot.name}: the bridge builds standard D-H chains only")
    model = pin.Model()
    model.name = robot.name
    parent = 0
    previous_link = pin.SE3.Identity()
    for i in range(robot.n_joints):
        placement = previous_link * pin.SE3(_rot_z(float(robot.dh[3, i])), np.zeros(3))
        parent = model.addJoint(
            parent,
            pin.JointModelRZ(),
            placement,
            f"joint{i + 1}",
            np.zeros(1),
            np.full(1, np.inf),
            np.array([robot.lower_rad[i]]),
            np.array([robot.upper_rad[i]]),
        )
        previous_link = _link(robot, i)
    model.addFrame(
        pin.Frame(FLANGE_FRAME, parent, previous_link, pin.FrameType.OP_FRAME)
    )
    return model


def _origin(xyz: tuple[float, float, float], rpy: tuple[float, float, float]) -> str:
    return (
        f'<origin xyz="{xyz[0]!r} {xyz[1]!r} {xyz[2]!r}" '
        f'rpy="{rpy[0]!r} {rpy[1]!r} {rpy[2]!r}"/>'
    )


def robot_to_urdf(robot: RobotModel) -> str:
    """URDF text of the robot, with a link named ``flange``.

    Each D-H link is written exactly, without converting rotations to roll-pitch-yaw: a fixed
    joint carries ``xyz = (a, 0, d)``, ``rpy = (α, 0, 0)``, and the next revolute joint's origin
    carries ``rpy = (0, 0, θ)`` and turns about z. Lengths in m, angles in rad, as URDF wants.

    Args:
        robot: The D-H robot, SI.

    Returns:
        The URDF document as a string.
    """
    if not robot.structure.is_standard:
        raise ValueError(f"{robot.name}: only standard D-H chains are written as URDF")
    lines = ['<?xml version="1.0"?>', f"<robot name={quoteattr(robot.name)}>",
             '  <link name="base_link"/>']
    parent = "base_link"
    for i in range(robot.n_joints):
        a, d, alpha, theta = (float(v) for v in robot.dh[:, i])
        link = f"link{i + 1}"
        lines += [
            f'  <link name="{link}"/>',
            f'  <joint name="joint{i + 1}" type="revolute">',
            f'    <parent link="{parent}"/>',
            f'    <child link="{link}"/>',
            "    " + _origin((0.0, 0.0, 0.0), (0.0, 0.0, theta)),
            '    <axis xyz="0 0 1"/>',
            f'    <limit lower="{float(robot.lower_rad[i])!r}" '
            f'upper="{float(robot.upper_rad[i])!r}" effort="0" velocity="0"/>',
            "  </joint>",
        ]
        end = FLANGE_FRAME if i == robot.n_joints - 1 else f"link{i + 1}_end"
        lines += [
            f'  <link name="{end}"/>',
            f'  <joint name="{end}_fixed" type="fixed">',
            f'    <parent link="{link}"/>',
            f'    <child link="{end}"/>',
            "    " + _origin((a, 0.0, d), (alpha, 0.0, 0.0)),
            "  </joint>",
        ]
        parent = end
    lines.append("</robot>")
    return "\n".join(lines) + "\n"
