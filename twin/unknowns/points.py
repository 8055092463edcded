"""Fixed points: where the places the tool point was brought to really are, in the base frame.

3 unknowns per named fixed point of the rig (``<name>_x``, ``<name>_y``, ``<name>_z``, a
correction of :attr:`twin.rig.Rig.points_m`), bounded to ±100 mm: the calibration starts each
at the mean of the nominal model's points of its rows. Such data cannot see a turn of the whole
fixture with the robot's first joint, nor a shift along that axis, and without a known distance
(``--distance``) not the scale either (docs/measurements.md).
"""

from __future__ import annotations

import numpy as np

from twin.rig import Rig
from twin.robot import RobotModel
from twin.units import mm_to_m
from twin.unknowns.group import Group, Stage

BOUND_M = float(mm_to_m(100.0))
"""Search bound on a fixed point's correction."""
RADIUS_M = float(mm_to_m(1.0))


def make(robot: RobotModel, rig: Rig) -> Group:
    """A correction of every fixed point of ``rig``."""
    if not rig.point_names:
        raise ValueError("points: the rig has no fixed point to correct")
    names = tuple(f"{name}_{axis}" for name in rig.point_names for axis in "xyz")
    p = len(names)
    return Group(name="points", stage=Stage.MEASUREMENT, names=names, units=("m",) * p,
                 lower=np.full(p, -BOUND_M), upper=np.full(p, BOUND_M),
                 radius=np.full(p, RADIUS_M))
