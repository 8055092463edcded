"""Planes (group ``planes``): a correction of each plane that touches of planes name, for
:mod:`twin.kinds.plane`.

3 unknowns per plane ``<name>_a``, ``<name>_b`` (rad) and ``<name>_d`` (m): the two angles that
turn the plane's normal from the one the calibration starts it at (about two axes in the start
plane) and the change of its offset from the base origin. The calibration starts each plane at
the plane fitted to the nominal model's points of its rows, so the corrections are small:
bounded to ±10° and ±100 mm.
"""

from __future__ import annotations

import numpy as np

from twin.rig import Rig
from twin.robot import RobotModel
from twin.units import deg_to_rad, mm_to_m
from twin.unknowns.group import Group, Stage

BOUND_RAD = float(deg_to_rad(10.0))
"""Search bound on each angle."""
BOUND_M = float(mm_to_m(100.0))
"""Search bound on each offset's change."""
RADIUS_RAD = float(deg_to_rad(1.0))
RADIUS_M = float(mm_to_m(5.0))


def make(robot: RobotModel, rig: Rig) -> Group:
    """A correction of every plane of the rig (:meth:`twin.rig.Rig.places`).

    Raises:
        ValueError: if the rig has no plane (touches of planes name them).
    """
    names = rig.places("planes")
    if not names:
        raise ValueError("group planes: the rig has no plane")
    one = np.array([BOUND_RAD, BOUND_RAD, BOUND_M])
    return Group(name="planes", stage=Stage.MEASUREMENT,
                 names=tuple(f"{name}_{key}" for name in names for key in "abd"),
                 units=("rad", "rad", "m") * len(names), lower=-np.tile(one, len(names)),
                 upper=np.tile(one, len(names)),
                 radius=np.tile([RADIUS_RAD, RADIUS_RAD, RADIUS_M], len(names)))
