"""Transmission error: a gear's error that repeats with the joint angle, added to each joint.

Per joint i, the first two harmonics of its recorded angle q_i::

    Δq_i = sin_q_i · sin q_i + cos_q_i · cos q_i + sin2_q_i · sin 2q_i + cos2_q_i · cos 2q_i

4n unknowns, joint by joint (``sin_q1``, ``cos_q1``, ``sin2_q1``, ``cos2_q1``, ``sin_q2``…), in
rad (results show degrees, like the D-H angles they trade with). The error of a reducer repeats
with the motor angle too, but at the joint the first two harmonics of q carry most of it
(method-notes §6).

A prismatic joint (a lift, a track) has no angle to repeat with: its transmission error is the
lead error of its screw or rack, a travel error that grows with the travel, ``Δq_i = scale_q_i
· q_i`` — one unknown ``scale_q{i}``, in m/m (results show µm/m), bounded by ±1000 µm/m
(racks and screws are 10–100 µm/m off their lead; a millimetre per metre would be a wrong
pitch), radius 50 µm/m. The periodic error of a screw repeats with its pitch, which a robot
file does not give: it is not modelled, and is left to the residual. A scale trades with δd of
the joint when its travel spans little (q a nearly constant times the scale).

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
from numpy.typing import ArrayLike

from twin.dataset import Measurements
from twin.rig import Rig
from twin.robot import RobotModel
from twin.units import SCALE_UNIT, deg_to_rad
from twin.unknowns.group import Array, Group, Stage, cached

BOUND_RAD = float(deg_to_rad(1.0))
"""Search bound on each harmonic coefficient."""
RADIUS_RAD = float(deg_to_rad(1.0 / 60.0))
"""Typical coefficient: 1 arc-minute."""
TERMS = ("sin_q", "cos_q", "sin2_q", "cos2_q")
"""The four terms of a revolute joint, in the order of x."""
SCALE_TERM = "scale_q"
"""The one term of a prismatic joint: its travel's scale (lead) error."""
SCALE_BOUND = 1e-3
"""Search bound on a prismatic joint's scale error, m/m (1000 µm/m)."""
SCALE_RADIUS = 5e-5
"""Typical scale error, m/m (50 µm/m)."""


def harmonics(q_rad: Array) -> Array:
    """sin q, cos q, sin 2q, cos 2q of every joint, shape (m, n, 4)."""
    return np.stack([np.sin(q_rad), np.cos(q_rad), np.sin(2.0 * q_rad), np.cos(2.0 * q_rad)],
                    axis=-1)


def terms(robot: RobotModel) -> tuple[tuple[int, str], ...]:
    """Each unknown as (joint, term), joint by joint: the four harmonics of a revolute joint,
    the scale of a prismatic one."""
    return tuple((i, term) for i, sliding in enumerate(robot.prismatic)
                 for term in ((SCALE_TERM,) if sliding else TERMS))


def unknowns(robot: RobotModel, harmonics_rad: ArrayLike, scale: ArrayLike) -> Array:
    """The group's unknowns, in its order, of given errors.

    Args:
        robot: The robot.
        harmonics_rad: Each joint's coefficients of sin q, cos q, sin 2q, cos 2q, shape (n, 4),
            rad: a revolute joint's.
        scale: Each joint's scale error, shape (n,), m/m: a prismatic joint's.

    Returns:
        Shape (p_g,).
    """
    rows, scales = np.asarray(harmonics_rad, dtype=np.float64), np.asarray(scale, dtype=float)
    return np.array([scales[i] if term == SCALE_TERM else rows[i, TERMS.index(term)]
                     for i, term in terms(robot)])


def make(robot: RobotModel, rig: Rig) -> Group:
    """The transmission error of every joint of ``robot``."""
    layout = terms(robot)
    joint = tuple(i for i, _ in layout)
    sliding = np.array([term == SCALE_TERM for _, term in layout])
    revolute = np.flatnonzero(~robot.prismatic)
    columns = np.flatnonzero(~sliding)

    def basis(data: Measurements) -> Array:
        if not robot.prismatic.any():
            return harmonics(data.q_rad).reshape(len(data), -1)  # joint by joint, as x
        values = np.empty((len(data), len(layout)))
        values[:, columns] = harmonics(data.q_rad[:, revolute]).reshape(len(data), -1)
        values[:, sliding] = data.q_rad[:, np.asarray(joint)[sliding]]
        return values

    return Group(
        name="transmission", stage=Stage.JOINTS,
        names=tuple(f"{term}{i + 1}" for i, term in layout),
        units=tuple(SCALE_UNIT if slide else "rad" for slide in sliding),
        lower=np.where(sliding, -SCALE_BOUND, -BOUND_RAD),
        upper=np.where(sliding, SCALE_BOUND, BOUND_RAD),
        radius=np.where(sliding, SCALE_RADIUS, RADIUS_RAD), basis=cached(basis), joint=joint,
    )
