"""Pinocchio bridge: a :class:`~twin.robot.RobotModel` as a ``pinocchio.Model``, and Pinocchio's
forward kinematics of a URDF, the referee of the robots read from and written back to URDFs.

An adapter: it imports Pinocchio, and nothing in the core imports it. (Reading a URDF is
:mod:`twin.io.urdf_reader`; writing one is :mod:`twin.export.urdf`.)

A robot of any parametrisation is its fixed transforms
(:func:`twin.geometry.kinematics.fixed_transforms`): joint i turns about z (or, prismatic, slides
along it) placed at T_{i−1} in joint i − 1's frame, and a frame named ``flange`` sits at T_n on
the last joint.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from twin.arrays import Array
from twin.geometry.kinematics import fixed_transforms
from twin.robot import RobotModel

FLANGE_FRAME = "flange"
"""Name of the flange frame in the Pinocchio model."""


def build_model(robot: RobotModel) -> pin.Model:
    """The robot as a Pinocchio model: n joints named as the robot's (revolute about z, or
    prismatic along z) and a ``flange`` frame.

    Joint limits are the robot's; ``model.lowerPositionLimit`` etc. are in rad (m for a
    prismatic joint). Link inertias are left empty: the model is for kinematics.

    Args:
        robot: The robot, SI, in any parametrisation.

    Returns:
        A ``pinocchio.Model`` with ``nq = robot.n_joints`` whose configuration is q in rad (m),
        the same q as :func:`twin.geometry.kinematics.flange_transform` takes.
    """
    fixed = fixed_transforms(robot.structure, robot.dh)
    model = pin.Model()
    model.name = robot.name
    parent = 0
    for i, name in enumerate(robot.joint_names):
        parent = model.addJoint(
            parent,
            pin.JointModelPZ() if robot.prismatic[i] else pin.JointModelRZ(),
            pin.SE3(fixed[i]),
            name,
            np.zeros(1),
            np.full(1, np.inf),
            np.array([robot.lower_rad[i]]),
            np.array([robot.upper_rad[i]]),
        )
    model.addFrame(pin.Frame(FLANGE_FRAME, parent, pin.SE3(fixed[-1]), pin.FrameType.OP_FRAME))
    return model


def configurations(model: pin.Model, joint_names: Sequence[str], q_rad: Array) -> Array:
    """Pinocchio configurations with the named joints at q (m, n), rad (m for a prismatic
    joint), and every other joint at its neutral value, shape (m, nq); a continuous joint takes
    (cos q, sin q)."""
    q = np.atleast_2d(q_rad)
    result = np.tile(pin.neutral(model), (len(q), 1))
    for column, name in enumerate(joint_names):
        joint = model.joints[model.getJointId(name)]
        if joint.nq == 2:
            result[:, joint.idx_q] = np.cos(q[:, column])
            result[:, joint.idx_q + 1] = np.sin(q[:, column])
        else:
            result[:, joint.idx_q] = q[:, column]
    return result


def urdf_flange(text: str, joint_names: Sequence[str], q_rad: Array, tip_link: str,
                base_link: str | None = None) -> Array:
    """base_T_tip of a URDF document by Pinocchio's forward kinematics, at joint values q.

    Args:
        text: The URDF document.
        joint_names: The joints q gives, in its column order.
        q_rad: Joint values, shape (m, n), rad (m for a prismatic joint).
        tip_link: The link whose frame is returned.
        base_link: The link it is expressed in; the URDF's root if None.

    Returns:
        Shape (m, 4, 4), m.
    """
    model = pin.buildModelFromXML(text)
    data = model.createData()
    tip = model.getFrameId(tip_link, pin.FrameType.BODY)
    base = None if base_link is None else model.getFrameId(base_link, pin.FrameType.BODY)
    poses = []
    for q in configurations(model, joint_names, q_rad):
        pin.framesForwardKinematics(model, data, q)
        pose = data.oMf[tip].homogeneous.copy()
        if base is not None:
            pose = np.linalg.inv(data.oMf[base].homogeneous) @ pose
        poses.append(pose)
    return np.array(poses)
