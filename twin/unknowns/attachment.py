"""Attachment point: where on the tool the measured point really is, in the flange frame.

3 unknowns ``attachment_x``, ``attachment_y``, ``attachment_z`` (a correction of the rig's
attachment, :attr:`twin.rig.Rig.attachment_m`), bounded to ±200 mm: an eyelet, a tool plate, a
tracker target or a ball on a stylus. The measured point is ``p = o_n + R_n t``; along the
flange axis t trades exactly with d6, sideways with a6 and θ6 (a6 + attachment_x, d6 +
attachment_z and a rotation of t about the flange axis are invisible to any measurement of the
point: docs/measurements.md). The point itself is identified; the flange centre then is not,
so compare the measured point's positions, not the flange's.
"""

from __future__ import annotations

import numpy as np

from twin.rig import Rig
from twin.robot import RobotModel
from twin.units import mm_to_m
from twin.unknowns.group import Group, Stage

BOUND_M = float(mm_to_m(200.0))
"""Search bound on each component of the attachment correction."""
RADIUS_M = float(mm_to_m(10.0))
"""A typical error of a told attachment (a ruler on a tool plate)."""


def make(robot: RobotModel, rig: Rig) -> Group:
    """A correction of the measured point in the flange frame."""
    return Group(name="attachment", stage=Stage.POINT,
                 names=("attachment_x", "attachment_y", "attachment_z"), units=("m",) * 3,
                 lower=np.full(3, -BOUND_M), upper=np.full(3, BOUND_M),
                 radius=np.full(3, RADIUS_M), linear=np.eye(3))
