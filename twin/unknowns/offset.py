"""Length offset: the unknown zero of a drawstring encoder, added to every modelled length.

One unknown, ``offset``, bounded to ±100 mm. It trades with nothing as long as the poses
spread the cable's direction; its σ says how well the zero is found.
"""

from __future__ import annotations

import numpy as np

from twin.rig import Rig
from twin.robot import RobotModel
from twin.units import mm_to_m
from twin.unknowns.group import Group, Stage

BOUND_M = float(mm_to_m(100.0))
"""Search bound on the length offset."""
RADIUS_M = float(mm_to_m(1.0))


def make(robot: RobotModel, rig: Rig) -> Group:
    """The encoder's length offset."""
    return Group(name="offset", stage=Stage.MEASUREMENT, names=("offset",), units=("m",),
                 lower=np.array([-BOUND_M]), upper=np.array([BOUND_M]),
                 radius=np.array([RADIUS_M]))
