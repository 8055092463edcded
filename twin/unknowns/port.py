"""Port corrections: where the cable really leaves each encoder port, in the base frame.

3 unknowns per estimated port of the rig (``port_x``… for one port, ``front_x``… for a port
named ``front``; :attr:`twin.rig.Rig.estimated_ports` says which, every port by default), bounded
to ±50 mm around the port the calibration is told; a port nobody measured
(:attr:`twin.rig.Rig.unknown_ports`: ``--port unknown``) is started from the data
(multilateration) and searched within ±:data:`UNKNOWN_BOUND_M` of that start, a drawstring's
whole reach, not the told port's box. A port that is measured is left out: its
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
UNKNOWN_BOUND_M = 2.0
"""Search bound on the correction of a port nobody measured, about its start from the data: a
drawstring encoder's whole reach (their cables run to 1.5-2 m)."""
RADIUS_M = float(mm_to_m(1.0))


def make(robot: RobotModel, rig: Rig) -> Group:
    """A correction of every estimated port of ``rig``."""
    if not len(rig.ports_m):
        raise ValueError("port: the rig has no port to correct")
    names = tuple(f"{rig.port_names[j]}_{axis}" for j in rig.estimated_port_index
                  for axis in "xyz")
    p = len(names)
    bound = np.repeat([UNKNOWN_BOUND_M if rig.port_names[j] in rig.unknown_ports else BOUND_M
                       for j in rig.estimated_port_index], 3)
    return Group(name="port", stage=Stage.MEASUREMENT, names=names, units=("m",) * p,
                 lower=-bound, upper=bound,
                 radius=np.full(p, RADIUS_M))
