"""A chain's joint axes as a parameter table: which parametrisation per joint, and the exact
conversion to it.

Any serial chain can be written as fixed transforms between joints,
``base_T_flange(q) = T_0 · J_1(q_1) · T_1 ⋯ J_n(q_n) · T_n``, J = Rz for a revolute joint and Tz
for a prismatic one (what a URDF, Pinocchio and :func:`twin.geometry.kinematics.fixed_transforms`
hold). :func:`convert` turns such a chain into a
:class:`~twin.geometry.kinematics.Structure` and a table with the same forward kinematics — every
joint in the parametrisation asked for, a base transform placing frame 0 on joint 1's axis and a
tool transform from the last joint's frame to the flange absorbing what the table cannot hold
(a URDF joint origin is a full rigid transform, six numbers; a table row holds four).

How the frames are placed (all at q = 0, in the base frame):

- **frame 0**: z along joint 1's axis, origin where the base origin projects onto that axis
  (where joint 2's origin projects, for a Hayati joint 1: it has no d to climb there), x the
  base x axis made perpendicular (the base y axis if x is along the axis);
- **standard D-H joint i** (``"dh"``): from a frame on axis i, the common normal to axis i + 1:
  d_i along axis i to its foot, θ_i turns x onto it, a_i its length, α_i turns the axis onto
  axis i + 1. For parallel axes the normal is taken through the incoming origin (d_i = 0); for
  intersecting axes x = ±z_i × z_{i+1}, the sign keeping θ_i nearest 0;
- **Hayati joint i** (``"hayati"``, for axis i + 1 nearly parallel to axis i): no d; the plane
  through the incoming origin perpendicular to axis i meets axis i + 1 at P: θ_i turns x towards
  P, a_i is the distance, and α_i (about x), β_i (about y) tilt the axis onto axis i + 1. The
  offset along the axes moves to the next joint;
- **modified D-H** (``"mdh"``, Craig; a whole chain, see below): frame i sits on axis i at the
  foot of the common normal to axis i + 1; joint i's a_i, α_i carry frame i − 1 onto axis i,
  θ_i and d_i move along axis i to that foot;
- **the last joint**: its frame goes on its axis where the flange origin projects (D-H: d_n;
  Hayati: no d, the offset goes to the tool), x towards the flange origin when it is off the
  axis (a_n), else the flange's x axis made perpendicular; α_n = β_n = 0; the tool transform
  holds the rest.

A prismatic joint's axis is a direction only: its line is kept where the source puts it (a
URDF joint's origin), so that the table's frames stay on the source's; at q = 0 its frames are
a revolute joint's, and the table is built alike — only how q enters differs
(:mod:`twin.geometry.kinematics`).

Standard D-H and Hayati joints mix freely (each ends on the next axis, where both start); a
modified D-H joint starts off its own axis and ends on it, so modified D-H is a whole chain:
mixed with the others, a link would be described twice (redundant a and α) or not at all.

:func:`choose` picks per joint from the nominal geometry: Hayati where axis i + 1 is within
:data:`PARALLEL_THRESHOLD_DEG` of axis i (parallel or antiparallel), standard D-H elsewhere.
Why: for axes at an angle φ, standard D-H's foot of the common normal lies about a / tan φ
along the axis (a the offset between the axes), and a tilt of the next axis by δ moves it by
about a · δ / sin²φ — at 10° already 33 times the link length per radian, and unbounded as φ
goes to 0, where a tilt of a few µrad needs metres of d. Hayati's β takes the tilt directly.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from twin.arrays import Array
from twin.geometry.kinematics import PARAMETRISATIONS, Structure, flange_transform

PARALLEL_THRESHOLD_DEG = 10.0
"""Consecutive axes closer than this to parallel (or antiparallel) get a Hayati joint."""
AUTO_PARAMETRISATION = "auto"
"""The parametrisation request that lets :func:`choose` decide per joint."""
REQUESTS = (*PARAMETRISATIONS, AUTO_PARAMETRISATION)
"""A whole-chain request: one parametrisation for every joint, or ``auto``."""
PARALLEL_EPS = 1e-12
"""|sin| of the angle between two axes below which they count as exactly parallel (the common
normal is then not unique); nominal geometries are parallel to round-off or clearly not."""
COINCIDENT_EPS_M = 1e-12
"""A common normal shorter than this, m, counts as zero: the axes intersect."""
HAYATI_MAX_DEG = 60.0
"""Largest angle between axes a Hayati joint is built for: beyond it the plane perpendicular
to axis i meets axis i + 1 far away, and standard D-H is the right choice."""
EXACT_M = 1e-9
"""The converted chain's flange must equal the source's to this, m (and rad), over random
poses; anything worse is refused rather than returned."""


def _unit(vector: Array) -> Array:
    return np.asarray(vector / np.linalg.norm(vector), dtype=np.float64)


def _angle_about(start: Array, end: Array, axis: Array) -> float:
    """The angle turning ``start`` towards ``end`` about ``axis`` (both perpendicular to it)."""
    return float(np.arctan2(np.dot(np.cross(start, end), axis), np.dot(start, end)))


def _perpendicular(vector: Array, axis: Array) -> Array:
    """``vector`` without its component along the unit ``axis``."""
    return np.asarray(vector - np.dot(vector, axis) * axis, dtype=np.float64)


def _frame(origin: Array, x: Array, z: Array) -> Array:
    transform = np.eye(4)
    transform[:3, 0], transform[:3, 1], transform[:3, 2] = x, np.cross(z, x), z
    transform[:3, 3] = origin
    return transform


def _rx(angle: float) -> Array:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ry(angle: float) -> Array:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def joint_frames(fixed: ArrayLike) -> tuple[Array, Array]:
    """Each joint's frame and the flange frame at q = 0, from the fixed transforms.

    Args:
        fixed: T_0..T_n, shape (n + 1, 4, 4): T_0 places joint 1 in the base frame, T_i joint
            i + 1 in joint i's frame, T_n the flange in joint n's; each joint turns about the
            z axis of its frame.

    Returns:
        ``(joints, flange)``: base_T_joint_i, shape (n, 4, 4), and base_T_flange, (4, 4), m.
    """
    transforms = np.asarray(fixed, dtype=np.float64)
    if transforms.ndim != 3 or transforms.shape[1:] != (4, 4) or len(transforms) < 2:
        raise ValueError(f"fixed: shape {transforms.shape}, expected (n + 1, 4, 4), n >= 1")
    frames = [transforms[0]]
    for step in transforms[1:-1]:
        frames.append(frames[-1] @ step)
    return np.stack(frames), frames[-1] @ transforms[-1]


def axis_angles_deg(fixed: ArrayLike) -> Array:
    """The angle between each pair of consecutive joint axes, 0° for parallel or antiparallel,
    shape (n − 1,), degrees."""
    joints, _ = joint_frames(fixed)
    z = joints[:, :3, 2]
    cosine = np.abs(np.sum(z[:-1] * z[1:], axis=1))
    sine = np.linalg.norm(np.cross(z[:-1], z[1:]), axis=1)
    return np.asarray(np.rad2deg(np.arctan2(sine, cosine)), dtype=np.float64)


def choose(fixed: ArrayLike, threshold_deg: float = PARALLEL_THRESHOLD_DEG) -> tuple[str, ...]:
    """Per joint, Hayati where the next axis is within ``threshold_deg`` of parallel to this
    joint's, standard D-H elsewhere (and for the last joint, which has no next axis)."""
    angles = axis_angles_deg(fixed)
    return (*tuple("hayati" if angle < threshold_deg else "dh" for angle in angles), "dh")


def resolve(request: str | Sequence[str], fixed: ArrayLike) -> tuple[str, ...]:
    """The per-joint parametrisation a request names: one of :data:`REQUESTS` for the whole
    chain (``auto``: :func:`choose`), or one of :data:`twin.geometry.kinematics.PARAMETRISATIONS`
    per joint.

    Raises:
        ValueError: for an unknown name, a list of the wrong length, or modified D-H mixed with
            the others.
    """
    n = len(np.asarray(fixed)) - 1
    if isinstance(request, str):
        if request not in REQUESTS:
            raise ValueError(f"parametrisation {request!r}: expected one of "
                             + ", ".join(REQUESTS) + " or a list of one per joint")
        kinds = choose(fixed) if request == AUTO_PARAMETRISATION else (request,) * n
    else:
        kinds = tuple(request)
        if len(kinds) != n or any(kind not in PARAMETRISATIONS for kind in kinds):
            raise ValueError(f"parametrisation {list(kinds)!r}: expected {n} of "
                             + ", ".join(PARAMETRISATIONS))
    check_mix(kinds)
    return kinds


def check_mix(kinds: Sequence[str]) -> None:
    """Refuse modified D-H joints mixed with standard D-H or Hayati joints (see the module
    docstring).

    Raises:
        ValueError: saying why.
    """
    if "mdh" in kinds and set(kinds) != {"mdh"}:
        raise ValueError("parametrisation: modified D-H describes a whole chain; mixed with "
                         "standard D-H or Hayati joints a link would be described twice")


def _common_normal(origin: Array, z: Array, point: Array, z_next: Array, x_previous: Array
                   ) -> tuple[float, float, Array, Array]:
    """The common normal from the axis (origin, z) to the axis (point, z_next).

    Returns:
        ``(d, a, x, foot)``: the foot's distance from ``origin`` along z, the normal's length,
        its direction (perpendicular to both axes) and its foot on the first axis.
    """
    cross = np.cross(z, z_next)
    sine = float(np.linalg.norm(cross))
    if sine < PARALLEL_EPS:
        # The normal is not unique: through the incoming origin.
        landing = point + np.dot(origin - point, z_next) * z_next
        normal = _perpendicular(landing - origin, z)
        length = float(np.linalg.norm(normal))
        x = normal / length if length >= COINCIDENT_EPS_M else x_previous
        return 0.0, length if length >= COINCIDENT_EPS_M else 0.0, x, origin
    w = origin - point
    b, dd, e = float(np.dot(z, z_next)), float(np.dot(z, w)), float(np.dot(z_next, w))
    height = (b * e - dd) / sine**2  # 1 − b² loses the digits of a small angle
    # The normal's direction and length from the cross product, not from the difference of
    # its ends: for nearly parallel axes those lie far away and their difference is round-off.
    direction = cross / sine
    length = float(np.dot(point - origin, direction))
    if abs(length) < COINCIDENT_EPS_M:
        x = direction if np.dot(direction, x_previous) >= 0 else -direction
        return height, 0.0, x, origin + height * z
    x = direction if length > 0 else -direction
    return height, abs(length), x, origin + height * z


def _towards_flange(origin: Array, z: Array, flange: Array, x_previous: Array
                    ) -> tuple[float, float, Array]:
    """For the last joint: the flange origin's height along the axis, its distance off it, and
    the direction towards it (the flange's x made perpendicular when it is on the axis)."""
    offset = flange[:3, 3] - origin
    height = float(np.dot(offset, z))
    sideways = _perpendicular(offset, z)
    distance = float(np.linalg.norm(sideways))
    if distance >= COINCIDENT_EPS_M:
        return height, distance, sideways / distance
    for candidate in (flange[:3, 0], flange[:3, 1], x_previous):
        along = _perpendicular(candidate, z)
        if np.linalg.norm(along) > 1e-6:
            return height, 0.0, _unit(along)
    return height, 0.0, x_previous  # unreachable: x_previous is perpendicular to z


def _frame_zero(joint_one: Array, through: Array | None = None) -> Array:
    """Frame 0: on joint 1's axis, where the base origin (or the point ``through``)
    projects, x from the base's."""
    z = joint_one[:3, 2]
    point = np.zeros(3) if through is None else through
    origin = joint_one[:3, 3] + np.dot(point - joint_one[:3, 3], z) * z
    for candidate in (np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])):
        x = _perpendicular(candidate, z)
        if np.linalg.norm(x) > 1e-6:
            return _frame(origin, _unit(x), z)
    raise AssertionError("x and y cannot both lie along one axis")


def _table_dh_hayati(kinds: tuple[str, ...], joints: Array, flange: Array
                     ) -> tuple[Array, Array]:
    """Standard D-H and Hayati joints: the table and frame 0."""
    n = len(kinds)
    table = np.zeros((4, n))
    # A Hayati joint 1 has no d: frame 0 then sits level with joint 2's origin, where the arm
    # is (a SCARA's shoulder), not down at the base.
    start = _frame_zero(joints[0], joints[1][:3, 3] if kinds[0] == "hayati" else None)
    frame = start
    for i, kind in enumerate(kinds):
        origin, x_prev, z = frame[:3, 3], frame[:3, 0], frame[:3, 2]
        if i == n - 1:
            height, distance, x = _towards_flange(origin, z, flange, x_prev)
            table[:, i] = (distance, height if kind == "dh" else 0.0, 0.0,
                           _angle_about(x_prev, x, z))
            break
        point, z_next = joints[i + 1][:3, 3], joints[i + 1][:3, 2]
        if kind == "dh":
            d, a, x, foot = _common_normal(origin, z, point, z_next, x_prev)
            alpha = _angle_about(z, z_next, x)
            table[:, i] = (a, d, alpha, _angle_about(x_prev, x, z))
            frame = _frame(foot + a * x, x, z_next)
            continue
        # Hayati: where the plane through the origin, perpendicular to z, meets the next axis.
        along = float(np.dot(z_next, z))
        if abs(along) < np.cos(np.deg2rad(HAYATI_MAX_DEG)):
            raise ValueError(f"joint {i + 1}: a Hayati joint needs the next axis within "
                             f"{HAYATI_MAX_DEG:g}° of parallel to its own")
        meet = point + np.dot(origin - point, z) / along * z_next
        sideways = _perpendicular(meet - origin, z)
        a = float(np.linalg.norm(sideways))
        x = sideways / a if a >= COINCIDENT_EPS_M else x_prev
        y = np.cross(z, x)
        local = np.array([np.dot(z_next, x), np.dot(z_next, y), np.dot(z_next, z)])
        beta = float(np.arctan2(local[0], np.hypot(local[1], local[2])))
        alpha = float(np.arctan2(-local[1], local[2]))
        table[:, i] = (a, beta, alpha, _angle_about(x_prev, x, z))
        rotation = np.column_stack([x, y, z]) @ _rx(alpha) @ _ry(beta)
        frame = np.eye(4)
        frame[:3, :3], frame[:3, 3] = rotation, origin + a * x
    return table, start


def _table_mdh(joints: Array, flange: Array) -> tuple[Array, Array]:
    """A modified D-H chain: the table and frame 0 (on joint 1's axis, so a_1 = α_1 = 0)."""
    n = len(joints)
    table = np.zeros((4, n))
    start = _frame_zero(joints[0])
    frame, landing = start, start[:3, 3]  # landing: where frame i − 1's x meets axis i
    for i in range(n):
        origin, x_prev, z_prev = frame[:3, 3], frame[:3, 0], frame[:3, 2]
        z = joints[i][:3, 2]
        a, alpha = float(np.dot(landing - origin, x_prev)), _angle_about(z_prev, z, x_prev)
        if i == n - 1:
            height, _, x = _towards_flange(landing, z, flange, x_prev)
            table[:, i] = (a, height, alpha, _angle_about(x_prev, x, z))
            break
        d, length, x, foot = _common_normal(landing, z, joints[i + 1][:3, 3],
                                            joints[i + 1][:3, 2], x_prev)
        table[:, i] = (a, d, alpha, _angle_about(x_prev, x, z))
        frame, landing = _frame(foot, x, z), foot + length * x
    return table, start


def convert(fixed: ArrayLike, request: str | Sequence[str] = AUTO_PARAMETRISATION,
            joint_types: Sequence[str] = ()) -> tuple[Structure, Array]:
    """The chain as a structure and table with the same forward kinematics.

    Args:
        fixed: T_0..T_n, shape (n + 1, 4, 4), m (see :func:`joint_frames`).
        request: ``auto``, one parametrisation for every joint, or one per joint
            (:func:`resolve`).
        joint_types: Each joint's type (:data:`twin.geometry.kinematics.JOINT_TYPES`); every
            joint revolute if empty.

    Returns:
        ``(structure, table)``: the table of shape (4, n), m and rad.

    Raises:
        ValueError: for a request :func:`resolve` refuses, a Hayati joint whose next axis is
            far from parallel, or a chain the result does not reproduce to :data:`EXACT_M`.
    """
    transforms = np.asarray(fixed, dtype=np.float64)
    kinds = resolve(request, transforms)
    joints, flange = joint_frames(transforms)
    if kinds[0] == "mdh":
        table, base = _table_mdh(joints, flange)
    else:
        table, base = _table_dh_hayati(kinds, joints, flange)
    bare = Structure(kinds, base=base, joint_types=tuple(joint_types))
    last = flange_transform(bare, table, np.zeros((1, len(kinds))))[0]
    tool = np.linalg.inv(last) @ flange
    tool[3] = (0.0, 0.0, 0.0, 1.0)
    structure = Structure(kinds, base=base, tool=tool, joint_types=bare.joint_types)
    _check_same(transforms, structure, table)
    return structure, table


def chain_flange(fixed: ArrayLike, q_rad: ArrayLike, joint_types: Sequence[str] = ()) -> Array:
    """base_T_flange of a chain of fixed transforms at joint values q (m, n), rad (m for a
    prismatic joint; every joint revolute if ``joint_types`` is empty): (m, 4, 4), m."""
    transforms = np.asarray(fixed, dtype=np.float64)
    q = np.atleast_2d(np.asarray(q_rad, dtype=np.float64))
    sliding = [kind == "prismatic" for kind in joint_types] or [False] * (len(transforms) - 1)
    result = np.broadcast_to(transforms[0], (len(q), 4, 4)).copy()
    for i in range(len(transforms) - 1):
        move = np.broadcast_to(np.eye(4), (len(q), 4, 4)).copy()
        if sliding[i]:
            move[:, 2, 3] = q[:, i]
        else:
            c, s = np.cos(q[:, i]), np.sin(q[:, i])
            move[:, 0, 0], move[:, 0, 1], move[:, 1, 0], move[:, 1, 1] = c, -s, s, c
        result = result @ move @ transforms[i + 1]
    return result


def _check_same(fixed: Array, structure: Structure, table: Array) -> None:
    q = np.random.default_rng(0).uniform(-np.pi, np.pi, (32, structure.n_joints))
    source = chain_flange(fixed, q, structure.joint_types)
    converted = flange_transform(structure, table, q)
    worst = float(np.max(np.abs(source - converted)))
    if not worst <= EXACT_M:
        raise ValueError(f"the {'/'.join(sorted(set(structure.parametrisation)))} chain "
                         f"differs from the source by {worst:.3g} (m or rad): the axes are too "
                         "close to parallel for standard D-H, use auto or hayati")
