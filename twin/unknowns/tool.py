"""Tool rotation (group ``tool``): a correction of the tool frame's rotation in the flange frame,
for instruments that read orientations (:mod:`twin.kinds.pose`).

3 unknowns ``tool_rx``, ``tool_ry``, ``tool_rz`` (rad): a rotation vector δ applied on the right
of the tool's rotation the calibration starts from, ``flange_R_tool = R_t · Exp(δ)``. The pose
kind starts R_t at the chordal mean of what the readings say of it, so δ is small: bounded to
±10°. With the attachment (group ``attachment``, the tool frame's origin) it is the tool
transform, 6-D, that ``--estimate-tool`` identifies.
"""

from __future__ import annotations

import numpy as np

from twin.rig import Rig
from twin.robot import RobotModel
from twin.units import deg_to_rad
from twin.unknowns.group import Group, Stage

BOUND_RAD = float(deg_to_rad(10.0))
"""Search bound on each component of the correction."""
RADIUS_RAD = float(deg_to_rad(1.0))


def make(robot: RobotModel, rig: Rig) -> Group:
    """A correction of the tool frame's rotation."""
    bound = np.full(3, BOUND_RAD)
    return Group(name="tool", stage=Stage.MEASUREMENT,
                 names=("tool_rx", "tool_ry", "tool_rz"), units=("rad",) * 3,
                 lower=-bound, upper=bound, radius=np.full(3, RADIUS_RAD))
