"""URDF for ROS and Pinocchio: revolute joints, exact D-H links, a link named ``flange``."""

from __future__ import annotations

from twin.pinocchio_bridge import robot_to_urdf
from twin.robot import RobotModel


def export(robot: RobotModel) -> str:
    """URDF text of the robot (see :func:`twin.pinocchio_bridge.robot_to_urdf`)."""
    return robot_to_urdf(robot)
