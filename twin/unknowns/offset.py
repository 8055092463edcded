"""Length offset: the unknown zero of a drawstring encoder, added to every modelled length.

One unknown, ``offset``, bounded to ±100 mm; with capture sessions (a ``session`` column,
:attr:`twin.rig.Rig.sessions`) one per session, ``offset_<session>``: a re-hooked cable or a
re-zeroed encoder starts a session with its own zero. It trades with nothing as long as the
poses spread the cable's direction; its σ says how well the zero is found.
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
    """The encoder's length offset, one per session of ``rig``."""
    names = tuple(f"offset_{name}" for name in rig.sessions) or ("offset",)
    p = len(names)
    return Group(name="offset", stage=Stage.MEASUREMENT, names=names, units=("m",) * p,
                 lower=np.full(p, -BOUND_M), upper=np.full(p, BOUND_M),
                 radius=np.full(p, RADIUS_M))
