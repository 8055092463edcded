"""Port corrections: where the cable really leaves each encoder port, in the base frame.

3 unknowns per estimated port of the rig (``port_x``… for one port, ``front_x``… for a port
named ``front``; :attr:`twin.rig.Rig.estimated_ports` says which, every port by default), bounded
to ±50 mm around the port the calibration is told. A port that is measured is left out: its
rows pin the base frame that the estimated ones cannot. Distances from a port that is itself
estimated cannot see a turn of the port about joint 1's axis or a shift along it: they trade
with δθ1 and δd1 (docs/identifiability.md).
"""

from __future__ import annotations

import numpy as np

from twin.rig import Rig
from twin.robot import RobotModel
from twin.units import mm_to_m
from twin.unknowns.group import Group, Stage

BOUND_M = float(mm_to_m(50.0))
"""Search bound on a port correction."""
RADIUS_M = float(mm_to_m(1.0))


def make(robot: RobotModel, rig: Rig) -> Group:
    """A correction of every estimated port of ``rig``."""
    if not len(rig.ports_m):
        raise ValueError("port: the rig has no port to correct")
    names = tuple(f"{rig.port_names[j]}_{axis}" for j in rig.estimated_port_index
                  for axis in "xyz")
    p = len(names)
    return Group(name="port", stage=Stage.MEASUREMENT, names=names, units=("m",) * p,
                 lower=np.full(p, -BOUND_M), upper=np.full(p, BOUND_M),
                 radius=np.full(p, RADIUS_M))
