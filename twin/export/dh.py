"""The D-H table in the `models/` TOML format (mm, degrees), loadable with ``--robot``."""

from __future__ import annotations

from twin.robot import RobotModel, robot_to_toml


def export(robot: RobotModel) -> str:
    """Model-file text of the robot; :func:`twin.robot.load_robot` reads it back exactly."""
    return robot_to_toml(robot)
