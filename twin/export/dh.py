"""The kinematic table in the `models/` TOML format (mm, degrees), loadable with ``--robot``.

A robot read from a URDF is written as a model file of its own (its table, parametrisation,
base and tool), without the URDF's names: ``urdf`` keeps those.
"""

from __future__ import annotations

from dataclasses import replace

from twin.io.robot_file import robot_to_toml
from twin.robot import RobotModel


def export(robot: RobotModel) -> str:
    """Model-file text of the robot; :func:`twin.io.robot_file.load_robot` reads it back exactly."""
    return robot_to_toml(replace(robot, urdf=None))
