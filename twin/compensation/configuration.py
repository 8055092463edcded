"""Which of a pose's joint solutions an arm takes: its configuration, as ABB's controllers state it.

A 6-axis arm with a wrist reaches most flange poses in eight ways (shoulder in front or behind,
elbow up or down, wrist flipped or not) and each with joints 1, 4 and 6 a whole turn apart. ABB's
``confdata`` (RAPID reference manual, data types ``confdata`` and ``robtarget``) names the one
meant with four integers:

- ``cf1``, ``cf4``, ``cf6``: the quarter turn axis 1, 4 and 6 stand in, ``floor(q / 90°)``
  (0 for [0°, 90°), −1 for [−90°, 0°), 1 for [90°, 180°)…);
- ``cfx = 4a + 2b + c`` for an arm of this kind (the IRB 120, 140, 1200…): a = 1 when the wrist
  centre is behind axis 1, b = 1 when it is behind the lower arm, c = 1 when axis 5 is negative.

"In front" is defined here geometrically, so that any 6-axis arm's table gives the same bits as
the controller's own model for it: as at the calibration position (every joint at 0, where ABB's
arms have their wrist in front of axis 1 and of the lower arm). Bit a is the side of the wrist
centre along the direction link 1 points in (the horizontal direction of the wrist centre at
q = 0, turned by q1 about axis 1); bit b its side of the lower arm (the line from axis 2 to
axis 3) within the arm's plane, the side it is on at q = 0 counting as in front. The wrist centre
is the point of axis 5 nearest to axis 4 (where axes 4, 5 and 6 meet on a spherical wrist).
Crossing a bit's boundary is crossing a singularity: the wrist centre on axis 1 (shoulder), on
the lower arm's line (the elbow stretched or folded), axis 5 at 0 (the wrist).

The configuration is always the *nominal* model's (the one the controller holds): it names the
branch a target was taught or written on, which the compensated joints must stay on.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import Array
from twin.compensation.ik import Starts
from twin.geometry.kinematics import joint_axes
from twin.robot import RobotModel

QUARTER_RAD = np.pi / 2
CONFIGURATION_JOINTS = 6
"""Joints of an arm whose configuration ``confdata`` names."""
TURNING = (0, 3, 5)
"""The joints whose quarter turn cf1, cf4 and cf6 give (axes 1, 4, 6)."""
CONFIGURATION_FIELDS = ("cf1", "cf4", "cf6", "cfx")



def _check(robot: RobotModel) -> None:
    if robot.n_joints != CONFIGURATION_JOINTS:
        raise ValueError(f"a configuration (cf1, cf4, cf6, cfx) is defined for a 6-axis arm, "
                         f"not one of {robot.n_joints} joints")


def quarter_turns(q_rad: ArrayLike) -> NDArray[np.int64]:
    """``floor(q / 90°)`` per angle: ABB's cf of a joint, same shape as q."""
    return np.floor(np.asarray(q_rad, dtype=np.float64) / QUARTER_RAD).astype(np.int64)


def _rotate(vectors: Array, axes: Array, angles: Array) -> Array:
    """Rodrigues: each vector (m, 3) turned about its unit axis (m, 3) by its angle (m,)."""
    c, s = np.cos(angles)[:, None], np.sin(angles)[:, None]
    return (vectors * c + np.cross(axes, vectors) * s
            + axes * np.sum(axes * vectors, axis=-1, keepdims=True) * (1.0 - c))


def _perpendicular(vectors: Array, axes: Array) -> Array:
    return vectors - axes * np.sum(vectors * axes, axis=-1, keepdims=True)


def _nearest_on_second(o1: Array, u1: Array, o2: Array, u2: Array) -> Array:
    """The point of line 2 nearest to line 1 (lines through o with unit direction u, (m, 3))."""
    w = o2 - o1
    b = np.sum(u1 * u2, axis=-1)
    d, e = np.sum(u1 * w, axis=-1), np.sum(u2 * w, axis=-1)
    denominator = 1.0 - b * b
    t = np.where(denominator > 1e-12, (b * d - e) / np.where(denominator > 1e-12, denominator,
                                                             1.0), 0.0)
    return o2 + u2 * t[:, None]


def _sides(robot: RobotModel, q: Array) -> tuple[Array, Array]:
    """Signed distances (m,) of the wrist centre in front of axis 1 and of the lower arm."""
    origins, axes = joint_axes(robot.structure, robot.dh, q)
    wrist = _nearest_on_second(origins[:, 3], axes[:, 3], origins[:, 4], axes[:, 4])
    o1, z1 = origins[:, 0], axes[:, 0]
    zero = np.zeros((1, robot.n_joints))
    origins0, axes0 = joint_axes(robot.structure, robot.dh, zero)
    wrist0 = _nearest_on_second(origins0[:, 3], axes0[:, 3], origins0[:, 4], axes0[:, 4])
    front0 = _perpendicular(wrist0 - origins0[:, 0], axes0[:, 0])
    # Axis 1 stands still, so link 1's front is the one at q = 0 turned by q1 about it.
    front = _rotate(np.broadcast_to(front0, (len(q), 3)), z1, q[:, 0])
    shoulder = np.sum((wrist - o1) * front, axis=-1)
    # The lower arm's normal in the arm's plane is fixed in link 2; its sign is the one that
    # puts the wrist in front at q = 0.
    o2, z2, o3 = origins[:, 1], axes[:, 1], origins[:, 2]
    normal = np.cross(z2, _perpendicular(o3 - o2, z2))
    normal0 = np.cross(axes0[:, 1], _perpendicular(origins0[:, 2] - origins0[:, 1], axes0[:, 1]))
    sign0 = np.sign(np.sum((wrist0 - origins0[:, 1]) * normal0, axis=-1))
    elbow = sign0 * np.sum((wrist - o2) * normal, axis=-1)
    return shoulder, elbow


def configuration(robot: RobotModel, q_rad: ArrayLike) -> NDArray[np.int64]:
    """The configuration ``(cf1, cf4, cf6, cfx)`` of joint angles on a 6-axis arm.

    Args:
        robot: The arm (the nominal model: the controller's).
        q_rad: Joint angles, shape (m, 6), rad.

    Returns:
        Shape (m, 4), integers (see the module docstring).
    """
    _check(robot)
    q = np.asarray(q_rad, dtype=np.float64).reshape(-1, robot.n_joints)
    shoulder, elbow = _sides(robot, q)
    cfx = 4 * (shoulder < 0) + 2 * (elbow < 0) + (q[:, 4] < 0)
    return np.column_stack([quarter_turns(q[:, list(TURNING)]), cfx.astype(np.int64)])


def branch_starts(robot: RobotModel, wanted: ArrayLike) -> Starts:
    """Random starting angles on each target's configuration: joints 1, 4, 6 in their quarter
    turn, joint 5 on the side bit c says, joints 2 and 3 anywhere within the limits (bits a and
    b are left to the solutions, which are then filtered by :func:`configuration`).

    Args:
        robot: The 6-axis arm.
        wanted: Configurations, shape (m, 4).
    """
    _check(robot)
    conf = np.asarray(wanted, dtype=np.int64).reshape(-1, 4)
    low = np.broadcast_to(robot.lower_rad, (len(conf), robot.n_joints)).copy()
    high = np.broadcast_to(robot.upper_rad, (len(conf), robot.n_joints)).copy()
    for column, joint in enumerate(TURNING):
        low[:, joint] = np.maximum(low[:, joint], conf[:, column] * QUARTER_RAD)
        high[:, joint] = np.minimum(high[:, joint], (conf[:, column] + 1) * QUARTER_RAD)
    negative = (conf[:, 3] & 1).astype(bool)
    high[negative, 4] = np.minimum(high[negative, 4], 0.0)
    low[~negative, 4] = np.maximum(low[~negative, 4], 0.0)
    # A quarter turn outside the limits leaves an empty range: draw within the limits instead
    # (the filter then rejects those starts, and the target is reported unreachable).
    empty = low >= high
    low[empty] = np.broadcast_to(robot.lower_rad, low.shape)[empty]
    high[empty] = np.broadcast_to(robot.upper_rad, high.shape)[empty]

    def draw(rng: np.random.Generator, k: int) -> Array:
        return rng.uniform(low, high, (k, *low.shape))

    return draw


def on_branch(robot: RobotModel, wanted: ArrayLike
              ) -> Callable[[Array, NDArray[np.intp]], NDArray[np.bool_]]:
    """A filter for :func:`twin.compensation.ik.nominal_ik`: whether solutions (k, 6) of target
    rows (k,) have the configuration wanted (m, 4) for those rows."""
    conf = np.asarray(wanted, dtype=np.int64).reshape(-1, 4)

    def accept(q_rad: Array, rows: NDArray[np.intp]) -> NDArray[np.bool_]:
        return np.all(configuration(robot, q_rad) == conf[rows], axis=1)

    return accept
