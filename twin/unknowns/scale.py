"""Encoder scale: the drawstring encoder's gain error, on every length it reads.

One unknown, ``scale`` (s), in m/m (results show it in ppm, µm/m): the length kind models a
reading as ``(1 + s) · ‖p − P‖ + c`` (:mod:`twin.kinds.length`) — a drum whose circumference,
or an encoder whose counts per millimetre, are off by s reads every extension that much too
long. Drawstring encoders are specified to some 100–1000 ppm of linearity and carry tens of ppm
of scale from their drum; bounded by ±5000 ppm (a wrong drum size or unit would be beyond),
radius 50 ppm.

What trades with it: a common scale of every length — the robot's link lengths, the port's
distance from the base, an estimated attachment — changes every distance by the same factor. With
the port told (measured beside the robot) the data see s; with the port estimated too, s and
that common scale are one direction the data cannot see (docs/identifiability.md), and it is
held. The scale is the instrument's, not the robot's: robot files exported from a result leave
it out.
"""

from __future__ import annotations

import numpy as np

from twin.rig import Rig
from twin.robot import RobotModel
from twin.units import MICRO, SCALE_UNIT
from twin.unknowns.group import Group, Stage

BOUND = 5000 / MICRO
"""Search bound on the scale, m/m (±5000 ppm)."""
RADIUS = 50 / MICRO
"""A typical scale error, m/m (50 ppm)."""


def make(robot: RobotModel, rig: Rig) -> Group:
    """The encoder's scale error."""
    return Group(name="scale", stage=Stage.MEASUREMENT, names=("scale",), units=(SCALE_UNIT,),
                 lower=np.array([-BOUND]), upper=np.array([BOUND]), radius=np.array([RADIUS]))
