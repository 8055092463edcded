"""Backlash (lost motion): each joint stops off its commanded angle by an amount whose sign is
the direction it approached the pose from.

Per joint i, ``Δq_i = b_i · s_i`` with s_i = ±1 the direction joint i last moved in before the
reading (the ``approach1..approachN`` columns of a measurement file, written by `twin simulate`
and `twin capture`). n unknowns ``backlash1``… in rad (results show degrees): b_i is half the
lash, positive when the joint ends beyond the commanded angle in the direction it moved, negative
when it stops short (which of the two depends on where the controller's encoder sits: motor or
joint). Without the directions backlash is indistinguishable from noise, so fitting it needs them.

Bounds ±0.5° (30 arc-minutes): the lash of industrial reducers is an arc-minute or less new and a
few worn; 0.5° would be a broken gear. Radius 1 arcmin.

On a prismatic joint (a lift, a track) backlash is its lost motion along the axis, in m (results
show mm): the same model, ``Δq_i = b_i · s_i``. Bounds ±1 mm (the lost motion of a screw or rack
drive is some 0.01–0.1 mm), radius 10 µm.

What trades with what: with every pose approached from the same side, b_i · s_i is a constant and
trades with δθ_i; the last joint's backlash is unseen at the flange centre (as every joint-6
error).
"""

from __future__ import annotations

import numpy as np

from twin.dataset import Measurements
from twin.rig import Rig
from twin.robot import RobotModel
from twin.units import deg_to_rad, mm_to_m
from twin.unknowns.group import Array, Group, Stage, cached

BOUND_RAD = float(deg_to_rad(0.5))
"""Search bound on each joint's backlash."""
RADIUS_RAD = float(deg_to_rad(1.0 / 60.0))
"""Typical backlash: 1 arc-minute."""
BOUND_M = float(mm_to_m(1.0))
"""Search bound on a prismatic joint's lost motion."""
RADIUS_M = float(mm_to_m(0.01))
"""Typical lost motion of a prismatic joint: 10 µm."""


def make(robot: RobotModel, rig: Rig) -> Group:
    """The backlash of every joint of ``robot``."""
    n = robot.n_joints

    def basis(data: Measurements) -> Array:
        if data.approach is None:
            raise ValueError("backlash: the measurements do not say the direction each joint "
                             "approached its pose from (approach)")
        return np.asarray(data.approach, dtype=np.float64)

    sliding = robot.prismatic
    bound = np.where(sliding, BOUND_M, BOUND_RAD)
    return Group(
        name="backlash", stage=Stage.JOINTS, names=tuple(f"backlash{i + 1}" for i in range(n)),
        units=robot.structure.joint_units, lower=-bound, upper=bound,
        radius=np.where(sliding, RADIUS_M, RADIUS_RAD), basis=cached(basis),
        joint=tuple(range(n)), needs_approach=True,
    )
