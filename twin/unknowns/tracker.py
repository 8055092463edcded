"""Tracker frame (group ``base``): a correction of where the robot base frame sits in the laser
tracker's frame.

6 unknowns ``base_x``, ``base_y``, ``base_z`` (m) and ``base_rx``, ``base_ry``, ``base_rz``
(rad) of a correction applied in the tracker frame on top of the rig's
:attr:`~twin.rig.Rig.base_in_tracker`: ``p_tracker = Rz Ry Rx(base_r) · (base_in_tracker ·
p_base) + base_xyz`` (:mod:`twin.geometry.rigid`). The calibration starts the rig's transform at a
rigid
fit (Kabsch) of the nominal model's points onto the measured ones, so the correction is small:
bounded to ±100 mm and ±10°. A tracker frame estimated freely absorbs a turn of the robot about
joint 1's axis and a shift along it: they trade with δθ1 and δd1 (docs/measurements.md).
"""

from __future__ import annotations

import numpy as np

from twin.rig import Rig
from twin.robot import RobotModel
from twin.units import deg_to_rad, mm_to_m
from twin.unknowns.group import Group, Stage

BOUND_M = float(mm_to_m(100.0))
"""Search bound on the translation of the correction."""
BOUND_RAD = float(deg_to_rad(10.0))
"""Search bound on each angle of the correction."""
RADIUS_M = float(mm_to_m(5.0))
RADIUS_RAD = float(deg_to_rad(1.0))


def make(robot: RobotModel, rig: Rig) -> Group:
    """A correction of the tracker-to-base transform."""
    bound = np.array([BOUND_M] * 3 + [BOUND_RAD] * 3)
    return Group(name="base", stage=Stage.MEASUREMENT,
                 names=("base_x", "base_y", "base_z", "base_rx", "base_ry", "base_rz"),
                 units=("m",) * 3 + ("rad",) * 3, lower=-bound, upper=bound,
                 radius=np.array([RADIUS_M] * 3 + [RADIUS_RAD] * 3))
