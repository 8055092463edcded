"""D-H errors: a correction to every entry of the kinematic parameter table (paper eq. 7).

4n unknowns in the table's slot order (``a1``…``an``, ``d1``…, ``alpha1``…, ``theta1``…; a
Hayati joint's second slot is ``beta``), bounded by the paper's search box: ±5 mm on lengths,
±8° on angles.
"""

from __future__ import annotations

import numpy as np

from twin.rig import Rig
from twin.robot import RobotModel
from twin.units import deg_to_rad, mm_to_m
from twin.unknowns.group import Group, Stage

BOUND_M = float(mm_to_m(5.0))
"""Search bound on a length error (paper: ±5 mm)."""
BOUND_RAD = float(deg_to_rad(8.0))
"""Search bound on an angle error (paper: ±8°)."""
RADIUS_M = float(mm_to_m(1.0))
"""Typical length error: the ±1 mm of BIPSO's first swarm (paper eq. 14)."""
RADIUS_RAD = float(deg_to_rad(1.0))
"""Typical angle error: ±1°."""


def make(robot: RobotModel, rig: Rig) -> Group:
    """The D-H errors of ``robot``'s table."""
    is_length = robot.structure.is_length.ravel()
    bound = np.where(is_length, BOUND_M, BOUND_RAD)
    return Group(
        name="dh", stage=Stage.TABLE, names=robot.structure.parameter_names,
        units=tuple("m" if length else "rad" for length in is_length),
        lower=-bound, upper=bound, radius=np.where(is_length, RADIUS_M, RADIUS_RAD),
        linear=np.eye(is_length.size),
    )
