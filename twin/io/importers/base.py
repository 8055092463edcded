"""What every importer gives back, and the checks they share."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from twin.dataset import Measurements
from twin.report.display import JOINT_ANGLE_DECIMALS, plain
from twin.robot import RobotModel
from twin.units import deg_to_rad, joint_file_units, joints_to_file


class Imported(NamedTuple):
    """Measurements read from files of another tool."""

    measurements: Measurements
    """The poses kept, SI."""
    dropped: list[str]
    """One line per row, message or window left out, saying why."""


@dataclass(frozen=True)
class StillRule:
    """When a recording's joints count as standing still.

    Attributes:
        tol_rad: Largest spread of every joint over the window, rad; a prismatic joint's, in
            m, is held to the same number (the travel of a point 1 m off a revolute axis).
        min_s: Shortest still window, s.
    """

    tol_rad: float = float(deg_to_rad(0.01))
    min_s: float = 0.5

    def __post_init__(self) -> None:
        for name in ("tol_rad", "min_s"):
            if not 0 < getattr(self, name) < math.inf:
                raise ValueError(f"{name}: {getattr(self, name)}, expected a positive number")


def outside_limits(q_rad: NDArray[np.float64], robot: RobotModel) -> str:
    """Why joint values (n,), rad (m for a prismatic joint), lie outside the robot's limits, or
    "" if they do not."""
    below, above = q_rad < robot.lower_rad - 1e-9, q_rad > robot.upper_rad + 1e-9
    bad = np.flatnonzero(below | above)
    if not bad.size:
        return ""
    j = int(bad[0])
    value, lower, upper = (joints_to_file(v, robot.prismatic)[j]
                           for v in (q_rad, robot.lower_rad, robot.upper_rad))
    unit = joint_file_units(robot.prismatic)[j]
    lower_text, upper_text = (plain(v, JOINT_ANGLE_DECIMALS) for v in (lower, upper))
    return (f"{robot.joint_names[j]} = {plain(value, JOINT_ANGLE_DECIMALS)} {unit} outside "
            f"[{lower_text}, {upper_text}] {unit}")
