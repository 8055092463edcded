"""Transmission error: a gear's error that repeats with the joint angle, added to each joint.

Per joint i, the first two harmonics of its recorded angle q_i::

    Δq_i = sin_q_i · sin q_i + cos_q_i · cos q_i + sin2_q_i · sin 2q_i + cos2_q_i · cos 2q_i

4n unknowns, joint by joint (``sin_q1``, ``cos_q1``, ``sin2_q1``, ``cos2_q1``, ``sin_q2``…), in
rad (results show degrees, like the D-H angles they trade with). The error of a reducer repeats
with the motor angle too, but at the joint the first two harmonics of q carry most of it
(method-notes §6).

Bounds ±1° on each coefficient: the transmission errors of industrial reducers are arc-minutes
(the paper scenario's twin has 2–4 arcmin), so a degree is far beyond any gear in working order
and still leaves the data, not the box, to decide. Radius 1 arcmin.

What trades with what (docs/identifiability.md):

- ``cos_q_i`` with δθ_i, and ``sin_q_i`` with δθ_i and a scale error of q_i, when the poses
  span little of joint i's range (over a narrow range, cos q and sin q are nearly a constant
  and a line); on poses spread over the joint's range they separate.
- Turning the last joint moves nothing on its axis: at the flange centre every term of the last
  joint (joint 6 of the IRB 120) is unseen; an attachment off that axis sees them.
"""

from __future__ import annotations

import numpy as np

from twin.dataset import Measurements
from twin.rig import Rig
from twin.robot import RobotModel
from twin.units import deg_to_rad
from twin.unknowns.group import Array, Group, Stage, cached

BOUND_RAD = float(deg_to_rad(1.0))
"""Search bound on each harmonic coefficient."""
RADIUS_RAD = float(deg_to_rad(1.0 / 60.0))
"""Typical coefficient: 1 arc-minute."""
TERMS = ("sin_q", "cos_q", "sin2_q", "cos2_q")
"""The four terms of a joint, in the order of x."""


def harmonics(q_rad: Array) -> Array:
    """sin q, cos q, sin 2q, cos 2q of every joint, shape (m, n, 4)."""
    return np.stack([np.sin(q_rad), np.cos(q_rad), np.sin(2.0 * q_rad), np.cos(2.0 * q_rad)],
                    axis=-1)


def make(robot: RobotModel, rig: Rig) -> Group:
    """The transmission error of every joint of ``robot``."""
    n = robot.n_joints
    p = len(TERMS) * n

    def basis(data: Measurements) -> Array:
        return harmonics(data.q_rad).reshape(len(data), p)  # joint by joint, as x

    return Group(
        name="transmission", stage=Stage.JOINTS,
        names=tuple(f"{term}{i + 1}" for i in range(n) for term in TERMS),
        units=("rad",) * p, lower=np.full(p, -BOUND_RAD), upper=np.full(p, BOUND_RAD),
        radius=np.full(p, RADIUS_RAD), basis=cached(basis),
        joint=tuple(i for i in range(n) for _ in TERMS),
    )
