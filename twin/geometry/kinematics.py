"""Forward kinematics of serial chains of revolute and prismatic joints, vectorised over poses
and over parameter tables.

A chain is a :class:`Structure` — one parametrisation and one joint type per joint, a fixed base
transform and a fixed tool transform — and a parameter table ``dh`` of shape (..., 4, n) whose
four rows are the joints' *slots*; any leading dimensions are a batch of K candidate tables.
Joint i contributes, with slots (s0, s1, s2, s3) and joint variable q_i:

- ``"dh"`` (standard, distal D-H), slots (a, d, α, θ): ``Rz(q + θ) · Tz(d) · Tx(a) · Rx(α)``;
- ``"mdh"`` (modified D-H, Craig), slots (a, d, α, θ) with a, α those of the link before the
  joint: ``Rx(α) · Tx(a) · Rz(q + θ) · Tz(d)``;
- ``"hayati"`` (Hayati–Mirmirani, for a joint whose axis is nearly parallel to the next one),
  slots (a, β, α, θ): ``Rz(q + θ) · Tx(a) · Rx(α) · Ry(β)`` — a small tilt of the next axis is a
  small β, where standard D-H needs a huge change of d.

That is a revolute joint (q in rad, added to θ). A prismatic joint slides by q (m) along the
same axis, z of the frame before it: q adds to d instead (``Rz(θ) · Tz(d + q) · Tx(a) · Rx(α)``,
``Rx(α) · Tx(a) · Rz(θ) · Tz(d + q)``), and a Hayati joint, which has no d, slides by q alone:
``Rz(θ) · Tz(q) · Tx(a) · Rx(α) · Ry(β)`` (its offset along the axis, like a revolute Hayati
joint's, is the next joint's). Arrays of joint values are "q_rad" throughout: radians for a
revolute joint, metres for a prismatic one.

``base_T_flange(q) = base · A_1(q_1) ⋯ A_n(q_n) · tool``. Lengths in m, angles in rad. The error
vector of a calibration keeps the table's layout, slot by slot: (s0 of joints 1..n, s1 of joints
1..n, s2 …, s3 …) — for an all-D-H arm the paper's (δa1..n, δd1..n, δα1..n, δθ1..n).

Positions are computed by carrying one point from the flange to the base through the elementary
motions (three components per step, no 4×4 products). A point's Jacobian along chosen directions
w (the cable's unit vector, or the base axes for the full Jacobian) carries w the other way, from
the base to the flange (:class:`PointTrace`): in the frame before a motion, with the point p and
the direction w expressed there, a translation along the local axis e moves w·p by w·e and a
rotation about e by w·(e × p) — no frames, axes or cross products in the base frame. Frames
(:func:`frames`, :func:`flange_jacobian`) are carried from the base to the flange. No loop over
poses or tables.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import cache, cached_property
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import Array, frozen_array, lengths, read_only
from twin.choices import KERNEL_VARIABLE
from twin.distribution import kernel_choice
from twin.geometry.rigid import is_rigid_transform

PARAMETRISATIONS = ("dh", "mdh", "hayati")
"""Per-joint parametrisations, see the module docstring."""
SLOT_NAMES = {"dh": ("a", "d", "alpha", "theta"), "mdh": ("a", "d", "alpha", "theta"),
              "hayati": ("a", "beta", "alpha", "theta")}
"""Name of each of the four slots, per parametrisation."""
SLOT_IS_LENGTH = {"dh": (True, True, False, False), "mdh": (True, True, False, False),
                  "hayati": (True, False, False, False)}
"""Whether each slot is a length (m) rather than an angle (rad), per parametrisation."""
JOINT_TYPES = ("revolute", "prismatic")
"""What a joint's variable moves (a URDF's names): it turns about the joint's axis (rad) or slides
along it (m); see the module docstring."""
JOINT_SLOT = 3
"""The slot a revolute joint's angle adds to (θ)."""
SLIDE_SLOT = 1
"""The slot a prismatic joint's travel adds to (d; a Hayati joint has none)."""
NO_SLOT = -1
"""The slot of a motion that holds no table entry: a prismatic Hayati joint's slide."""

_ROT, _TRANS = 0, 1
_X, _Y, _Z = 0, 1, 2
_MOTIONS = {
    "dh": ((_ROT, _Z, 3), (_TRANS, _Z, 1), (_TRANS, _X, 0), (_ROT, _X, 2)),
    "mdh": ((_ROT, _X, 2), (_TRANS, _X, 0), (_ROT, _Z, 3), (_TRANS, _Z, 1)),
    "hayati": ((_ROT, _Z, 3), (_TRANS, _X, 0), (_ROT, _X, 2), (_ROT, _Y, 1)),
}
"""Elementary motions of each parametrisation's revolute joint, base side first: (kind, local
axis, slot)."""


@cache
def joint_motions(parametrisation: str, joint_type: str
                  ) -> tuple[tuple[int, int, int, bool], ...]:
    """The elementary motions of one joint, base side first: (kind, local axis, slot, driven),
    ``driven`` for the one motion q moves (θ's turn, or the slide along z), ``slot``
    :data:`NO_SLOT` for a prismatic Hayati joint's slide."""
    motions = _MOTIONS[parametrisation]
    if joint_type == "revolute":
        return tuple((kind, axis, slot, slot == JOINT_SLOT) for kind, axis, slot in motions)
    if parametrisation == "hayati":
        (kind, axis, slot), *rest = motions
        return ((kind, axis, slot, False), (_TRANS, _Z, NO_SLOT, True),
                *((kind, axis, slot, False) for kind, axis, slot in rest))
    return tuple((kind, axis, slot, kind == _TRANS and slot == SLIDE_SLOT)
                 for kind, axis, slot in motions)


def _identity() -> Array:
    return np.eye(4)


@dataclass(frozen=True)
class Structure:
    """What a parameter table means: the parametrisation and type of each joint and the fixed
    ends.

    Attributes:
        parametrisation: One of :data:`PARAMETRISATIONS` per joint, base to flange.
        base: Fixed transform from the robot's base frame to the chain's frame 0, (4, 4), m.
        tool: Fixed transform from the last joint's frame to the flange frame, (4, 4), m.
        joint_types: One of :data:`JOINT_TYPES` per joint; every joint revolute if empty.
    """

    parametrisation: tuple[str, ...]
    base: Array = field(default_factory=_identity)
    tool: Array = field(default_factory=_identity)
    joint_types: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        kinds = tuple(self.parametrisation)
        unknown = [kind for kind in kinds if kind not in PARAMETRISATIONS]
        if not kinds or unknown:
            raise ValueError(f"parametrisation {kinds!r}: expected one or more of "
                             + ", ".join(PARAMETRISATIONS))
        object.__setattr__(self, "parametrisation", kinds)
        types = tuple(self.joint_types) or ("revolute",) * len(kinds)
        if len(types) != len(kinds) or any(kind not in JOINT_TYPES for kind in types):
            raise ValueError(f"joint_types {types!r}: expected one of "
                             + ", ".join(JOINT_TYPES) + f" for each of {len(kinds)} joints")
        object.__setattr__(self, "joint_types", types)
        for name in ("base", "tool"):
            transform = frozen_array(getattr(self, name), (4, 4), name)
            if not is_rigid_transform(transform):
                raise ValueError(f"{name}: not a rigid transform")
            object.__setattr__(self, name, transform)

    @classmethod
    def standard(cls, n_joints: int) -> Structure:
        """n standard D-H revolute joints, base and tool frames at the chain's ends."""
        return cls(("dh",) * n_joints)

    @property
    def n_joints(self) -> int:
        """Number of joints n."""
        return len(self.parametrisation)

    @property
    def prismatic(self) -> NDArray[np.bool_]:
        """Whether each joint slides (its q in m) rather than turns (rad), shape (n,)."""
        return np.array([kind == "prismatic" for kind in self.joint_types], dtype=bool)

    @cached_property
    def all_revolute(self) -> bool:
        """Every joint revolute: the kernel's shortest path."""
        return all(kind == "revolute" for kind in self.joint_types)

    @property
    def joint_units(self) -> tuple[str, ...]:
        """The SI unit of each joint's variable: ``rad`` (revolute) or ``m`` (prismatic)."""
        return tuple("m" if kind == "prismatic" else "rad" for kind in self.joint_types)

    @property
    def joint_columns(self) -> NDArray[np.intp]:
        """Where each joint's variable sits among a trace's derivative columns (the error
        vector's 4n, then a column per prismatic Hayati joint's slide), shape (n,): θ_i's
        column for a revolute joint, d_i's for a prismatic one."""
        return _joint_columns(self.parametrisation, self.joint_types)

    @cached_property
    def n_columns(self) -> int:
        """Number of a trace's derivative columns: the table's 4n and one per prismatic Hayati
        joint's slide (which holds no table entry)."""
        return 4 * self.n_joints + sum(kind == "hayati" and joint_type == "prismatic"
                                       for kind, joint_type in zip(self.parametrisation,
                                                                   self.joint_types,
                                                                   strict=True))

    @property
    def is_standard(self) -> bool:
        """All joints standard D-H, base and tool the identity (the paper's form)."""
        return all(kind == "dh" for kind in self.parametrisation) \
            and bool(np.allclose(self.base, np.eye(4), atol=0.0)) \
            and bool(np.allclose(self.tool, np.eye(4), atol=0.0))

    @property
    def slot_names(self) -> tuple[tuple[str, ...], ...]:
        """Names of the slots per joint, shape (n, 4) as nested tuples."""
        return tuple(SLOT_NAMES[kind] for kind in self.parametrisation)

    @property
    def is_length(self) -> NDArray[np.bool_]:
        """Whether each table entry is a length (m) rather than an angle (rad), shape (4, n)."""
        return np.array([SLOT_IS_LENGTH[kind] for kind in self.parametrisation]).T

    @property
    def parameter_names(self) -> tuple[str, ...]:
        """Names of the table entries in the error vector's order: slot by slot, joints 1..n
        (``a1``…``a6``, ``d1``… or ``beta2`` for a Hayati joint, …)."""
        return tuple(f"{self.slot_names[joint][slot]}{joint + 1}"
                     for slot in range(4) for joint in range(self.n_joints))


class Frames(NamedTuple):
    """Frames 0..n of a chain (frame 0 = base · nothing, frame i after joint i's transform)
    and the flange frame, for a batch of tables and poses.

    Attributes:
        origins: Frame origins in the base frame, shape (..., m, n+1, 3), m.
        x_axes: Frame x axes, shape (..., m, n+1, 3), unit vectors.
        y_axes: Frame y axes, shape (..., m, n+1, 3).
        z_axes: Frame z axes, shape (..., m, n+1, 3).
        flange: base_T_flange, shape (..., m, 4, 4).
    """

    origins: Array
    x_axes: Array
    y_axes: Array
    z_axes: Array
    flange: Array


class PointJacobian(NamedTuple):
    """A point on the flange, and how it moves with the table, the joints and the point, along r
    directions per pose (:meth:`PointTrace.jacobian`; the base axes, r = 3, unless chosen)."""

    position: Array
    """The point in the base frame, shape (..., m, 3), m."""
    table: Array
    """w·∂p/∂table in the error vector's order, shape (..., m, r, 4n), m/m or m/rad."""
    joints: Array
    """w·∂p/∂q, shape (..., m, r, n), m/rad (m/m for a prismatic joint)."""
    rotation: Array
    """w·∂p/∂(point in the flange frame), shape (..., m, r, 3): along the base axes the flange's
    rotation base_R_flange."""


def _check_shapes(structure: Structure, dh: Array, q_rad: Array) -> None:
    n = structure.n_joints
    if dh.ndim < 2 or dh.shape[-2:] != (4, n):
        raise ValueError(f"dh: shape {dh.shape}, expected (..., 4, {n})")
    if q_rad.ndim < 2 or q_rad.shape[-1] != n:
        raise ValueError(f"q_rad: shape {q_rad.shape}, expected (..., m, {n})")


class Turns(NamedTuple):
    """Joint angles with their cosines and sines, joint-major and contiguous: what every
    evaluation on the same poses reuses (a fit never changes its measured joints; make them
    once per data set with :func:`turns`, and :meth:`shifted` for angles moved by x). A
    prismatic joint's values (m) are kept as they are; the kernel never reads their cosines.

    Attributes:
        q_rad: The angles as given, shape (..., m, n), rad.
        cos: cos q, joint-major, shape (n, ..., m).
        sin: sin q, joint-major, shape (n, ..., m).
    """

    q_rad: Array
    cos: Array
    sin: Array

    def shifted(self, delta_rad: ArrayLike) -> Turns:
        """The angles q + δ, their cosines and sines by the angle-sum identity (the
        transcendentals run on δ alone); δ of shape (..., m, n), rad."""
        delta = np.asarray(delta_rad, dtype=np.float64)
        moved = np.moveaxis(delta, -1, 0)
        c, s = np.cos(moved), np.sin(moved)
        ndim = max(moved.ndim, self.cos.ndim)
        cq, sq = _joint_major(self.cos, ndim), _joint_major(self.sin, ndim)
        return Turns(self.q_rad + delta, cq * c - sq * s, sq * c + cq * s)


def turns(q_rad: ArrayLike | Turns) -> Turns:
    """Joint angles q (..., m, n), rad, with their cosines and sines (:class:`Turns`); a
    :class:`Turns` is returned as it is."""
    if isinstance(q_rad, Turns):
        return q_rad
    q = np.asarray(q_rad, dtype=np.float64)
    major = np.ascontiguousarray(np.moveaxis(q, -1, 0))
    return Turns(q, np.cos(major), np.sin(major))


def _joint_major(array: Array, ndim: int) -> Array:
    """(n, batch..., m) to (n, 1..., batch..., m) with ``ndim`` dimensions, for broadcasting."""
    return array.reshape(array.shape[0], *(1,) * (ndim - array.ndim), *array.shape[1:])


def _cos_sin(structure: Structure, dh: Array, angles: Turns
             ) -> tuple[int, list[tuple[Array, ...]], Array]:
    """Per joint and slot the values the motions need, joint-major and broadcastable.

    Returns:
        ``(ndim, per_joint, slots)``: per joint a tuple (cos, sin) for each slot, where the joint
        slot's angle is q + θ (by the angle-sum identity, from the poses' cached cos q, sin q
        and the tables' cos θ, sin θ: no transcendental runs on a table-pose pair) and other
        angle slots are table-only; ``slots`` the table joint-major, shape
        (4, n, 1..., batch..., 1). Every array is contiguous with the poses innermost.
    """
    ndim = max(dh.ndim, angles.q_rad.ndim)  # of (n, batch..., m) once joint-major
    table = np.moveaxis(dh, (-2, -1), (0, 1))  # (4, n, batch...)
    slots = np.ascontiguousarray(table.reshape(4, structure.n_joints,
                                               *(1,) * (ndim - dh.ndim), *table.shape[2:], 1))
    cq, sq = _joint_major(angles.cos, ndim), _joint_major(angles.sin, ndim)
    cos_slots, sin_slots = np.cos(slots), np.sin(slots)
    ct = cq * cos_slots[JOINT_SLOT] - sq * sin_slots[JOINT_SLOT]
    st = sq * cos_slots[JOINT_SLOT] + cq * sin_slots[JOINT_SLOT]
    per_joint = []
    for i, joint_type in enumerate(structure.joint_types):
        values = [(cos_slots[k, i], sin_slots[k, i]) for k in range(4)]
        if joint_type == "revolute":  # a prismatic joint's θ is the table's alone
            values[JOINT_SLOT] = (ct[i], st[i])
        per_joint.append(tuple(v for pair in values for v in pair))
    return ndim, per_joint, slots


def _slide(q_rad: Array, joint: int, ndim: int) -> Array:
    """Joint ``joint``'s values of q (..., m, n) shaped as one joint of a joint-major array of
    ``ndim`` dimensions, (1..., batch..., m): the travel a prismatic joint adds to its slot."""
    values = q_rad[..., joint]
    return values.reshape(*(1,) * (ndim - 1 - values.ndim), *values.shape)


_BULK = [False]


def for_bulk_work() -> None:
    """Take the compiled kernel from now on in this process under ``TWIN_KERNEL=auto``: a
    process that evaluates many calibrations (a study's worker) pays numba's import (about half
    a second of CPU) once and gains on every one, while a single command would pay more to
    import it than the kernel saves (an LM fit takes milliseconds)."""
    _BULK[0] = True
    _compiled.cache_clear()


@contextmanager
def bulk_work() -> Iterator[None]:
    """:func:`for_bulk_work` for a block, this process's choice restored after it: a study's
    first trial runs in the command's process, whose caller may calibrate afterwards, and a
    swarm's answer depends on the kernel (BIPSO's does: docs/methods.md)."""
    before = _BULK[0]
    try:
        yield
    finally:
        _BULK[0] = before
        _compiled.cache_clear()


def takes_compiled() -> bool:
    """Whether this process takes the compiled kernels (extra ``fast``): the one switch of
    :data:`KERNEL_VARIABLE` and :func:`for_bulk_work`, which the swarms' compiled B-spline step
    (:mod:`twin.solvers.compiled`) follows too."""
    return _compiled() is not None


def load_compiled() -> None:
    """Load (on a fresh install, compile and cache) every kernel of
    :mod:`twin.geometry.compiled` as this module hands them arrays in bulk work (read-only, so
    one version each): ``make test`` runs it and :func:`twin.solvers.compiled.load` beside
    mypy, where a fresh clone's tests had compiled both modules' kernels in each of their
    processes, some 26 s of CPU apiece. Nothing is loaded where the numpy path is forced
    (``TWIN_KERNEL=numpy``) or numba is not installed."""
    structure = Structure.standard(2)
    with bulk_work():
        for_bulk_work()
        trace = trace_point(structure, np.zeros((1, 4, 2)), np.zeros((3, 2)))
        trace.jacobian(np.ones((3, 1, 3)))
        distances(trace.position, np.zeros((3, 3)))
        point_distances(structure, np.zeros((1, 4, 2)), np.zeros((3, 2)), None,
                        np.zeros((3, 3)))
        point_sum_squares(structure, np.zeros((1, 4, 2)), np.zeros((3, 2)), None,
                          np.zeros((3, 3)), np.ones(3))
        compiled_position_ik(structure, np.zeros((4, 2)), np.zeros((1, 3)), np.zeros((1, 2)),
                             1e-10, 1, (1e-6, 1e-12, 1e8))


@cache
def _compiled() -> Any:
    """The compiled kernel's module, or None (``TWIN_KERNEL=numpy``, or ``auto`` outside bulk
    work or without numba).

    Raises:
        UnknownChoiceError, MissingExtraError: as :func:`twin.distribution.kernel_choice`; and
            the latter for ``TWIN_KERNEL=numba`` where numba is found but fails to import.
    """
    mode = kernel_choice()
    if mode == "numpy" or (mode == "auto" and not _BULK[0]):
        return None
    try:
        from twin.geometry import compiled
    except ImportError as exc:
        if mode == "auto":  # the compiled kernel where it can be had
            return None
        from twin.distribution import missing_extra

        missing = missing_extra(exc, source=KERNEL_VARIABLE)
        if missing is None:
            raise
        raise missing from exc
    return compiled


@cache
def _plan_rows(parametrisation: tuple[str, ...], joint_types: tuple[str, ...]
               ) -> NDArray[np.int64]:
    """The motions base to flange as rows (kind, axis, slot, joint, driven, column, whole),
    shape (motions, 7): what the compiled kernel reads. ``whole`` is 1 on the flange-side
    motion of a revolute standard D-H joint, whose four motions the kernel carries a point
    through in one pass over the poses."""
    rows = [[kind, axis, slot, joint, int(driven), column, 0]
            for kind, axis, _, _, slot, joint, driven, column in _plan(parametrisation,
                                                                        joint_types)]
    last = -1
    for name, joint_type in zip(parametrisation, joint_types, strict=True):
        last += len(joint_motions(name, joint_type))
        rows[last][6] = int(name == "dh" and joint_type == "revolute")
    return read_only(np.ascontiguousarray(rows, dtype=np.int64))


_NO_SLIDES = read_only(np.zeros((0, 1, 1)))
"""The compiled kernel's joint values for a chain without a prismatic joint (never read)."""


class _Compiled(NamedTuple):
    """The inputs of the compiled kernel, batch dimensions flattened."""

    batch: tuple[int, ...]
    table: Array
    cos: Array
    sin: Array
    slides: Array
    start: Array
    base: Array
    tool: Array


def _compiled_inputs(structure: Structure, dh: Array, angles: Turns,
                     point_m: ArrayLike | None) -> _Compiled | None:
    """The kernel's inputs, or None where the batch shapes are beyond it (the numpy path
    broadcasts any): tables (K, 4, n), angles of the poses or one set per table, a point or one
    per table, the structure's base and tool transforms; every array read-only, whether the
    caller's was or not (a model's table is, a swarm's candidates are not; a data set's cached
    angles are, fresh poses' are not), so that each kernel has one compiled version
    (:func:`twin.arrays.read_only`)."""
    batch = dh.shape[:-2]
    size = math.prod(batch)
    q_batch = angles.q_rad.shape[:-2]
    local = np.zeros(3) if point_m is None else np.asarray(point_m, dtype=np.float64)
    if q_batch not in ((), batch) or local.shape[:-1] not in ((), batch) or size == 0:
        return None
    n, m = structure.n_joints, angles.q_rad.shape[-2]
    start = (local @ structure.tool[:3, :3].T + structure.tool[:3, 3]).reshape(-1, 3)
    shape = (n, size if q_batch else 1, m)
    slides = _NO_SLIDES if structure.all_revolute \
        else np.moveaxis(angles.q_rad, -1, 0).reshape(shape)
    return _Compiled(batch, *(read_only(np.ascontiguousarray(array)) for array in (
        dh.reshape(size, 4, n), angles.cos.reshape(shape), angles.sin.reshape(shape), slides,
        start, structure.base, structure.tool)))


def point_position(structure: Structure, dh: ArrayLike, q_rad: ArrayLike | Turns,
                   point_m: ArrayLike | None = None) -> Array:
    """A point fixed to the flange, in the base frame.

    Args:
        structure: What the table means.
        dh: Parameter tables, shape (..., 4, n), m and rad.
        q_rad: Joint values, shape (m, n) or (..., m, n), rad (m for a prismatic joint), or
            their :class:`Turns` (cosines and sines made once for the poses).
        point_m: The point in the flange frame, shape (3,) or (..., 3) (batched with the
            tables), m; the flange centre (origin) if None.

    Returns:
        base_p_point, shape (..., m, 3), m.
    """
    # The hot path of the swarms: one point carried from the flange to the base,
    # p ← motion(p), on joint-major arrays.
    dh = np.asarray(dh, dtype=np.float64)
    angles = turns(q_rad)
    _check_shapes(structure, dh, angles.q_rad)
    compiled = _compiled()
    inputs = None if compiled is None else _compiled_inputs(structure, dh, angles, point_m)
    if inputs is not None:
        out = compiled.positions(inputs.table, _plan_rows(structure.parametrisation,
                                                          structure.joint_types),
                                 inputs.cos, inputs.sin, inputs.slides, inputs.start,
                                 inputs.base)
        return np.asarray(out.reshape(*inputs.batch, -1, 3))
    ndim, per_joint, slots = _cos_sin(structure, dh, angles)
    local = np.zeros(3) if point_m is None else np.asarray(point_m, dtype=np.float64)
    start = local @ structure.tool[:3, :3].T + structure.tool[:3, 3]  # (..., 3)
    p = [start[..., k, None] for k in range(3)]  # (..., 1): broadcast over the poses
    for kind, axis, j, k, slot, i, driven, _ in reversed(_plan(structure.parametrisation,
                                                               structure.joint_types)):
        if kind == _TRANS:
            value = slots[slot, i] if slot != NO_SLOT else 0.0
            if driven:
                value = value + _slide(angles.q_rad, i, ndim)
            p[axis] = p[axis] + value
            continue
        c, s = per_joint[i][2 * slot], per_joint[i][2 * slot + 1]
        p[j], p[k] = c * p[j] - s * p[k], s * p[j] + c * p[k]
    position = np.stack(np.broadcast_arrays(*p), axis=-1)
    rotation, translation = structure.base[:3, :3], structure.base[:3, 3]
    return np.asarray(position @ rotation.T + translation, dtype=np.float64)


def distances(points_m: ArrayLike, anchors_m: ArrayLike) -> Array:
    """The distance of each point from its anchor, ‖p − a‖ over the last axis.

    Args:
        points_m: Points, shape (..., m, 3), m.
        anchors_m: The anchor of each row, shape (m, 3) or the points' (..., m, 3), m.

    Returns:
        Shape (..., m), m: :func:`twin.arrays.lengths` of the differences, bit for bit; in one
        pass of the compiled kernel where it is taken (a swarm's batch of candidates: no
        (..., m, 3) temporaries).
    """
    points = np.asarray(points_m, dtype=np.float64)
    anchors = np.asarray(anchors_m, dtype=np.float64)
    batch = points.shape[:-2]
    compiled = _compiled()
    if compiled is None or points.ndim < 2 or points.shape[-1] != 3 or points.size == 0 \
            or anchors.shape not in (points.shape[-2:], points.shape):
        return lengths(points - anchors)
    out = compiled.distances(*(read_only(np.ascontiguousarray(array.reshape(
        -1, *points.shape[-2:]))) for array in (points, anchors)))
    return np.asarray(out.reshape(*batch, -1))


def point_distances(structure: Structure, dh: ArrayLike, q_rad: ArrayLike | Turns,
                    point_m: ArrayLike | None, anchors_m: ArrayLike) -> Array:
    """The distance of a point fixed to the flange from each row's anchor (a cable's port).

    Args:
        structure, dh, q_rad, point_m: As :func:`point_position`.
        anchors_m: The anchor of each pose, shape (m, 3) or the tables' (..., m, 3), m.

    Returns:
        Shape (..., m), m: :func:`distances` of :func:`point_position`, bit for bit; in one
        pass of the compiled kernel where it is taken, without the points' (..., m, 3) array
        (a swarm's candidates: :func:`twin.geometry.compiled.anchored_distances`).
    """
    dh, angles, anchors = _anchored_arrays(structure, dh, q_rad, anchors_m)
    inputs = _anchored_inputs(structure, dh, angles, point_m, anchors)
    if inputs is None:
        return distances(point_position(structure, dh, angles, point_m), anchors)
    compiled, anchored = inputs
    out = _compiled().anchored_distances(*_kernel_chain(structure, compiled), anchored)
    return np.asarray(out.reshape(*compiled.batch, -1))


def point_sum_squares(structure: Structure, dh: ArrayLike, q_rad: ArrayLike | Turns,
                      point_m: ArrayLike | None, anchors_m: ArrayLike, readings_m: ArrayLike
                      ) -> Array:
    """Σ_i (d_i − L_i)² over the rows, d_i the distances of :func:`point_distances` and L_i
    the rows' readings: a least-squares cost of ranges.

    Args:
        structure, dh, q_rad, point_m, anchors_m: As :func:`point_distances`.
        readings_m: Each row's reading, shape (m,), m.

    Returns:
        Shape (...,), m²: on the numpy path ``np.sum((d − L)**2, axis=-1)``, bit for bit; on
        the compiled kernel summed in the distances' pass, the same to round-off
        (:func:`twin.geometry.compiled.anchored_sum_squares`: no (..., m) arrays).
    """
    dh, angles, anchors = _anchored_arrays(structure, dh, q_rad, anchors_m)
    readings = np.asarray(readings_m, dtype=np.float64)
    inputs = _anchored_inputs(structure, dh, angles, point_m, anchors)
    if inputs is None or readings.shape != angles.q_rad.shape[-2:-1]:
        residuals = point_distances(structure, dh, angles, point_m, anchors) - readings
        return np.asarray(np.sum(residuals**2, axis=-1), dtype=np.float64)
    compiled, anchored = inputs
    out = _compiled().anchored_sum_squares(*_kernel_chain(structure, compiled), anchored,
                                           read_only(np.ascontiguousarray(readings)))
    return np.asarray(out.reshape(compiled.batch))


def _anchored_arrays(structure: Structure, dh: ArrayLike, q_rad: ArrayLike | Turns,
                     anchors_m: ArrayLike) -> tuple[Array, Turns, Array]:
    """The tables, the angles and the anchors of :func:`point_distances`, checked."""
    table = np.asarray(dh, dtype=np.float64)
    angles = turns(q_rad)
    _check_shapes(structure, table, angles.q_rad)
    return table, angles, np.asarray(anchors_m, dtype=np.float64)


def _anchored_inputs(structure: Structure, dh: Array, angles: Turns, point_m: ArrayLike | None,
                     anchors: Array) -> tuple[_Compiled, Array] | None:
    """The compiled kernel's inputs and the anchors as it reads them, (1 or K, m, 3); None
    where the numpy path is taken (no kernel, or batch shapes beyond it)."""
    inputs = None if _compiled() is None \
        else _compiled_inputs(structure, dh, angles, point_m)
    m = angles.q_rad.shape[-2]
    if inputs is None or anchors.shape[-2:] != (m, 3) \
            or anchors.shape[:-2] not in ((), inputs.batch):
        return None
    return inputs, read_only(np.ascontiguousarray(anchors.reshape(-1, m, 3)))


def _kernel_chain(structure: Structure, inputs: _Compiled) -> tuple[np.ndarray, ...]:
    """The chain's arguments every anchored kernel takes first: table, plan, cos q, sin q,
    slides, start, base."""
    return (inputs.table, _plan_rows(structure.parametrisation, structure.joint_types),
            inputs.cos, inputs.sin, inputs.slides, inputs.start, inputs.base)


_Moved = tuple[int, int, bool, Array, Array]
"""A motion as :func:`_walk` records it: (kind, joint, driven, axis u, origin o), u and o in the
base frame at that motion."""


def _walk(structure: Structure, dh: ArrayLike, q_rad: ArrayLike, record: bool
          ) -> tuple[list[tuple[Array, ...]], list[_Moved], Array]:
    """Frames after each joint, base to flange, carrying origin and axes.

    Returns:
        ``(frames, motions, flange)``: frames 0..n as (origin, x, y, z), each (..., m, 3); if
        ``record``, every motion (:data:`_Moved`); the flange frame as (..., m, 4, 4).
    """
    dh = np.asarray(dh, dtype=np.float64)
    q_rad = np.asarray(q_rad, dtype=np.float64)
    _check_shapes(structure, dh, q_rad)
    batch = np.broadcast_shapes((*dh.shape[:-2], 1), q_rad.shape[:-1])
    table = np.broadcast_to(dh[..., None, :, :], (*batch, 4, structure.n_joints))
    q = np.broadcast_to(q_rad, (*batch, structure.n_joints))
    base = structure.base
    axes = [np.broadcast_to(base[:3, k], (*batch, 3)) for k in range(3)]
    origin = np.broadcast_to(base[:3, 3], (*batch, 3))
    frames: list[tuple[Array, ...]] = [(origin, *axes)]
    motions: list[_Moved] = []
    for i, (name, joint_type) in enumerate(zip(structure.parametrisation,
                                               structure.joint_types, strict=True)):
        for kind, axis, slot, driven in joint_motions(name, joint_type):
            value = table[..., slot, i, None] if slot != NO_SLOT else np.zeros((*batch, 1))
            if driven:
                value = value + q[..., i, None]
            if record:
                motions.append((kind, i, driven, axes[axis], origin))
            if kind == _TRANS:
                origin = origin + value * axes[axis]
                continue
            c, s = np.cos(value), np.sin(value)
            j, k = (axis + 1) % 3, (axis + 2) % 3
            axes[j], axes[k] = c * axes[j] + s * axes[k], c * axes[k] - s * axes[j]
        frames.append((origin, *axes))
    last = np.stack(axes, axis=-1)  # (..., m, 3, 3), columns x, y, z
    tool = structure.tool
    flange = np.zeros((*batch, 4, 4))
    flange[..., :3, :3] = last @ tool[:3, :3]
    flange[..., :3, 3] = origin + last @ tool[:3, 3]
    flange[..., 3, 3] = 1.0
    return frames, motions, flange


def flange_transform(structure: Structure, dh: ArrayLike, q_rad: ArrayLike) -> Array:
    """Homogeneous flange pose in the base frame, base_T_flange, shape (..., m, 4, 4), m."""
    return _walk(structure, dh, q_rad, record=False)[2]


def frames(structure: Structure, dh: ArrayLike, q_rad: ArrayLike) -> Frames:
    """Frames 0..n and the flange, for drawing a robot or differentiating its chain."""
    joint_frames, _, flange = _walk(structure, dh, q_rad, record=False)
    origins, x_axes, y_axes, z_axes = (np.stack(parts, axis=-2)
                                       for parts in zip(*joint_frames, strict=True))
    return Frames(origins, x_axes, y_axes, z_axes, flange)


def joint_axes(structure: Structure, dh: ArrayLike, q_rad: ArrayLike) -> tuple[Array, Array]:
    """Where each joint turns (or slides): a point on its axis and the axis' direction, in the
    base frame.

    Args:
        structure: What the table means.
        dh: Parameter tables, shape (..., 4, n), m and rad.
        q_rad: Joint values, shape (m, n) or (..., m, n), rad (m for a prismatic joint).

    Returns:
        ``(origins, axes)``: shapes (..., m, n, 3), m and unit vectors; a positive joint rate
        turns everything beyond joint i about ``axes[..., i, :]`` through ``origins[..., i, :]``
        (for a D-H joint, frame i−1's z axis through its origin), or for a prismatic joint
        moves it along ``axes[..., i, :]``.
    """
    _, motions, flange = _walk(structure, dh, q_rad, record=True)
    turns = [(u, o) for _, _, driven, u, o in motions if driven]
    shape = (*flange.shape[:-2], 3)
    origins = np.stack([np.broadcast_to(o, shape) for _, o in turns], axis=-2)
    axes = np.stack([np.broadcast_to(u, shape) for u, _ in turns], axis=-2)
    return origins, axes


def point_jacobian(structure: Structure, dh: ArrayLike, q_rad: ArrayLike,
                   point_m: ArrayLike | None = None) -> PointJacobian:
    """A flange point and its analytic Jacobians w.r.t. the table, the joints and the point.

    Args:
        structure: What the table means.
        dh: Parameter tables, shape (..., 4, n), m and rad.
        q_rad: Joint values, shape (m, n) or (..., m, n), rad (m for a prismatic joint).
        point_m: The point in the flange frame, shape (3,) or (..., 3), m; origin if None.

    Returns:
        ∂p/∂(·) along the base axes: table (..., m, 3, 4n), joints (..., m, 3, n), rotation
        (..., m, 3, 3).
    """
    return trace_point(structure, dh, q_rad, point_m).jacobian()


_Motion = tuple[int, int, int, int, int, int, bool, int]
"""An elementary motion of a chain: (kind, local axis, j, k, slot, joint, driven, column); a
rotation turns axis j towards k; ``driven`` for the motion the joint's variable moves;
``column`` where its derivative goes among a trace's columns: slot · n + joint for a table entry
(the error vector's order), 4n onwards for the prismatic Hayati joints' slides."""
_Step = tuple[int, int, int, int, int, Any, Any, list[Array] | None]
"""One elementary motion as :class:`PointTrace` keeps it: (kind, axis, j, k, column of the error
vector, cos, sin, the point in the frame before the motion); cos, sin and the point are None
for a translation."""


@cache
def _plan(parametrisation: tuple[str, ...], joint_types: tuple[str, ...]
          ) -> tuple[_Motion, ...]:
    """The elementary motions of a chain, base to flange (:func:`joint_motions` per joint)."""
    n = len(parametrisation)
    plan, extra = [], 4 * n
    for joint, (name, joint_type) in enumerate(zip(parametrisation, joint_types, strict=True)):
        for kind, axis, slot, driven in joint_motions(name, joint_type):
            column = slot * n + joint if slot != NO_SLOT else extra
            extra += slot == NO_SLOT
            plan.append((kind, axis, (axis + 1) % 3, (axis + 2) % 3, slot, joint, driven,
                         column))
    return tuple(plan)


@cache
def _joint_columns(parametrisation: tuple[str, ...], joint_types: tuple[str, ...]
                   ) -> NDArray[np.intp]:
    """:attr:`Structure.joint_columns` (read-only)."""
    columns = np.array([motion[7] for motion in _plan(parametrisation, joint_types)
                        if motion[6]], dtype=np.intp)
    columns.setflags(write=False)
    return columns


def _split_columns(structure: Structure, columns: Array) -> tuple[Array, Array]:
    """A trace's derivative columns (..., 4n + slides) as (table (..., 4n), joints (..., n))."""
    n = structure.n_joints
    table = columns[..., :4 * n] if columns.shape[-1] > 4 * n else columns
    if structure.all_revolute:  # every joint's column is θ's: a view, no copy
        return table, table[..., JOINT_SLOT * n:(JOINT_SLOT + 1) * n]
    return table, columns[..., structure.joint_columns]


class PointTrace:
    """A point fixed to the flange, carried to the base frame for a batch of tables and poses,
    with what its derivatives need (made by :func:`trace_point`).

    Attributes:
        position: The point in the base frame, shape (..., m, 3), m.
    """

    def __init__(self, structure: Structure, position: Array, steps: list[_Step],
                 shape: tuple[int, ...]) -> None:
        self.position = position
        self._structure = structure
        self._steps = steps
        self._shape = shape  # (batch..., 1, m): what every carried component broadcasts to

    def jacobian(self, directions: ArrayLike | None = None) -> PointJacobian:
        """How the point moves along r directions per pose: w·∂p/∂table, w·∂p/∂q and
        w·∂p/∂(point in the flange frame) for each direction w.

        The directions are carried from the base to the flange, each step expressing w in the
        frame before the next motion; there a translation along the local axis e gives w·e and
        a rotation about e gives w·(e × p), p the point in that frame (kept from the way in).

        Args:
            directions: Directions in the base frame, shape (..., m, r, 3) (batched with the
                tables); the base axes (r = 3, the whole Jacobian) if None.

        Returns:
            table (..., m, r, 4n), joints (..., m, r, n), rotation (..., m, r, 3).
        """
        structure = self._structure
        base_R = structure.base[:3, :3]
        if directions is None:  # R_baseᵀ e_row, the same at every pose: (3, r = 3, 1)
            w_local = base_R.T[:, :, None]
        else:
            w_m = np.asarray(directions, dtype=np.float64)
            nd = w_m.ndim
            along = w_m.transpose(nd - 1, *range(nd - 3), nd - 2, nd - 3)  # (3, batch..., r, m)
            w_local = (base_R.T @ along.reshape(3, -1)).reshape(along.shape)
        w = list(w_local)
        shape = np.broadcast_shapes(w_local.shape[1:], self._shape)
        columns = np.empty((structure.n_columns, *shape))
        for kind, axis, j, k, column, c, s, before in self._steps:
            if kind == _TRANS:
                columns[column] = w[axis]
                continue
            assert before is not None
            columns[column] = w[k] * before[j] - w[j] * before[k]
            w[j], w[k] = c * w[j] + s * w[k], c * w[k] - s * w[j]  # R_eᵀ w
        last = np.empty((3, *shape))
        for k in range(3):
            last[k] = w[k]
        flange = (structure.tool[:3, :3].T @ last.reshape(3, -1)).reshape(last.shape)
        # (3 or columns, batch..., r, m) to (batch..., m, r, 3 or columns)
        order = (*range(1, columns.ndim - 2), columns.ndim - 1, columns.ndim - 2, 0)
        table, joints = _split_columns(structure, columns.transpose(order))
        return PointJacobian(self.position, table, joints, flange.transpose(order))


class CompiledTrace:
    """:class:`PointTrace` computed by the compiled kernel (:mod:`twin.geometry.compiled`), for
    the batch shapes it takes (made by :func:`trace_point`).

    Attributes:
        position: The point in the base frame, shape (..., m, 3), m.
    """

    def __init__(self, structure: Structure, inputs: _Compiled) -> None:
        self._structure = structure
        self._inputs = inputs
        self._plan = _plan_rows(structure.parametrisation, structure.joint_types)
        out = _compiled().positions(inputs.table, self._plan, inputs.cos, inputs.sin,
                                    inputs.slides, inputs.start, inputs.base)
        self.position = np.asarray(out.reshape(*inputs.batch, -1, 3))

    def jacobian(self, directions: ArrayLike | None = None) -> PointJacobian:
        """As :meth:`PointTrace.jacobian`."""
        inputs, structure = self._inputs, self._structure
        m = self.position.shape[-2]
        if directions is None:
            w = np.eye(3)[None, None]
        else:
            w_m = np.asarray(directions, dtype=np.float64)
            if w_m.shape[:-3] not in ((), inputs.batch):
                w_m = np.broadcast_to(w_m, (*inputs.batch, *w_m.shape[-3:]))
            w = w_m.reshape(-1, *w_m.shape[-3:])
        _, columns, rotation = _compiled().jacobian(
            inputs.table, self._plan, inputs.cos, inputs.sin, inputs.slides, inputs.start,
            inputs.base, inputs.tool, read_only(np.ascontiguousarray(w)),
            structure.n_columns)
        table, joints = _split_columns(structure, columns.reshape(*inputs.batch, m, -1,
                                                                  structure.n_columns))
        return PointJacobian(self.position, table, joints,
                             rotation.reshape(*inputs.batch, m, -1, 3))


def compiled_position_ik(structure: Structure, dh: ArrayLike, targets_m: ArrayLike,
                         seeds_rad: ArrayLike, tolerance_m: float, max_iterations: int,
                         damping: tuple[float, float, float]) -> tuple[Array, Array, int] | None:
    """Damped Newton steps bringing the flange centre (the tool applied) to each target, every
    row in one call of the compiled kernel (:func:`twin.geometry.compiled.position_ik`, the
    steps :func:`twin.compensation.ik.solve_ik` takes in numpy), or None where this process
    takes the numpy path (:func:`takes_compiled`).

    Args:
        structure: What the table means.
        dh: The table, shape (4, n), m and rad.
        targets_m: Targets in the base frame, shape (m, 3), m.
        seeds_rad: Starting joint values, shape (m, n), rad (m on a slide).
        tolerance_m: A row is done within this distance, m.
        max_iterations: Lockstep iterations at most.
        damping: The first damping, the smallest and the one at which a row gives up.

    Returns:
        ``(q, error, iterations)``: joint values (m, n), target − flange (m, 3), m, and the
        iterations run.
    """
    kernel = _compiled()
    if kernel is None:
        return None
    n = structure.n_joints
    table, targets, seeds, start, base, tool, columns = (
        read_only(np.ascontiguousarray(array, dtype=dtype)) for array, dtype in (
            (np.reshape(dh, (1, 4, n)), np.float64), (targets_m, np.float64),
            (seeds_rad, np.float64), (structure.tool[None, :3, 3], np.float64),
            (structure.base, np.float64), (structure.tool, np.float64),
            (structure.joint_columns, np.int64)))
    q, error, iterations = kernel.position_ik(
        table, _plan_rows(structure.parametrisation, structure.joint_types), start, base, tool,
        structure.n_columns, columns, targets, seeds, float(tolerance_m), int(max_iterations),
        *(float(value) for value in damping))
    return np.asarray(q), np.asarray(error), int(iterations)


def trace_point(structure: Structure, dh: ArrayLike, q_rad: ArrayLike | Turns,
                point_m: ArrayLike | None = None) -> PointTrace | CompiledTrace:
    """A point fixed to the flange, in the base frame, kept for its derivatives.

    Args:
        structure: What the table means.
        dh: Parameter tables, shape (..., 4, n), m and rad.
        q_rad: Joint values, shape (m, n) or (..., m, n), rad (m for a prismatic joint), or
            their :class:`Turns`.
        point_m: The point in the flange frame, shape (3,) or (..., 3) (batched with the
            tables), m; the flange centre (origin) if None.
    """
    # As point_position (the point carried from the flange to the base), with every carried
    # component kept for PointTrace.jacobian; arrays are
    # joint-major with a row axis (batch..., 1, m), so that r directions broadcast over it.
    dh = np.asarray(dh, dtype=np.float64)
    angles = turns(q_rad)
    _check_shapes(structure, dh, angles.q_rad)
    inputs = None if _compiled() is None else _compiled_inputs(structure, dh, angles, point_m)
    if inputs is not None:
        return CompiledTrace(structure, inputs)
    n = structure.n_joints
    batch = max(dh.ndim, angles.q_rad.ndim) - 2
    table = dh.transpose(dh.ndim - 2, dh.ndim - 1, *range(dh.ndim - 2))  # (4, n, batch...)
    table = table.reshape(4, n, *(1,) * (batch - table.ndim + 2), *table.shape[2:], 1, 1)
    cq, sq = (v.reshape(n, *(1,) * (batch - v.ndim + 2), *v.shape[1:-1], 1, v.shape[-1])
              for v in (angles.cos, angles.sin))  # (n, batch..., 1, m)
    values, cos_values, sin_values = table, np.cos(table), np.sin(table)
    # cos(q + θ), sin(q + θ) by the angle sum, from the poses' cached cos q and sin q
    cos_turned = cq * cos_values[JOINT_SLOT] - sq * sin_values[JOINT_SLOT]
    sin_turned = sq * cos_values[JOINT_SLOT] + cq * sin_values[JOINT_SLOT]
    if dh.ndim == 2:  # one table: its entries as numbers, not (1, 1) arrays, which numpy
        # multiplies half as fast again
        values, cos_values, sin_values = (v[..., 0, 0].tolist()
                                          for v in (values, cos_values, sin_values))
    local = np.zeros(3) if point_m is None else np.asarray(point_m, dtype=np.float64)
    start = local @ structure.tool[:3, :3].T + structure.tool[:3, 3]  # (..., 3)
    p = [start[..., k, None, None] for k in range(3)]
    steps: list[_Step] = []
    for kind, axis, j, k, slot, i, driven, column in reversed(_plan(structure.parametrisation,
                                                                    structure.joint_types)):
        if kind == _TRANS:
            value = values[slot][i] if slot != NO_SLOT else 0.0
            if driven:  # (batch..., 1, m), as cq
                value = value + _slide(angles.q_rad, i, batch + 2)[..., None, :]
            p[axis] = p[axis] + value
            steps.append((kind, axis, j, k, column, None, None, None))
            continue
        if driven:
            c, s = cos_turned[i], sin_turned[i]
        else:
            c, s = cos_values[slot][i], sin_values[slot][i]
        p[j], p[k] = c * p[j] - s * p[k], s * p[j] + c * p[k]
        steps.append((kind, axis, j, k, column, c, s, list(p)))
    steps.reverse()
    shape = np.broadcast_shapes(cos_turned.shape[1:], *(v.shape for v in p))
    position = np.empty((*shape, 3))
    for k in range(3):
        position[..., k] = p[k]
    rotation, translation = structure.base[:3, :3], structure.base[:3, 3]
    return PointTrace(structure, np.asarray(position[..., 0, :, :] @ rotation.T + translation,
                                            dtype=np.float64), steps, shape)


def flange_jacobian(structure: Structure, dh: ArrayLike, q_rad: ArrayLike
                    ) -> tuple[Array, Array]:
    """Flange pose and its geometric joint Jacobian, for inverse kinematics.

    Column i is the flange's linear velocity (m/rad; m/m for a prismatic joint) and angular
    velocity (rad/rad; zero for a prismatic joint) in the base frame per unit rate of joint i.

    Returns:
        ``(base_T_flange, jacobian)``: shapes (..., m, 4, 4) and (..., m, 6, n), rows
        (vx, vy, vz, wx, wy, wz).
    """
    _, motions, flange = _walk(structure, dh, q_rad, record=True)
    driven = [motion for motion in motions if motion[2]]
    linear = _columns(driven, flange[..., :3, 3])
    angular = np.stack([u if kind == _ROT else np.zeros(u.shape) for kind, _, _, u, _ in driven],
                       axis=-1)
    return flange, np.concatenate([linear, angular], axis=-2)


def flange_turn_jacobian(structure: Structure, dh: ArrayLike, q_rad: ArrayLike
                         ) -> tuple[Array, Array, Array]:
    """The flange's orientation and how it turns: base_R_flange (..., m, 3, 3); its angular
    velocity in the base frame per unit of each table entry, shape (..., m, 3, 4n) in the error
    vector's order (a rotation's axis, zero for a translation); and per unit rate of each
    joint, shape (..., m, 3, n) (a revolute joint's axis, zero for a prismatic one)."""
    _, motions, flange = _walk(structure, dh, q_rad, record=True)
    n = structure.n_joints
    slots = [slot for name, joint_type in zip(structure.parametrisation, structure.joint_types,
                                              strict=True)
             for _, _, slot, _ in joint_motions(name, joint_type)]
    table = np.zeros((*flange.shape[:-2], 3, 4 * n))
    joints = np.zeros((*flange.shape[:-2], 3, n))
    for (kind, joint, driven, axis, _), slot in zip(motions, slots, strict=True):
        if kind == _ROT:
            table[..., slot * n + joint] = axis
            if driven:
                joints[..., joint] = axis
    return flange[..., :3, :3], table, joints


def _columns(motions: list[_Moved], p: Array) -> Array:
    """How the point p moves with each motion: u for a translation along u, u × (p − o) for a
    rotation about u through o; shape (..., m, 3, len(motions)), all in one cross product."""
    u = np.stack([motion[3] for motion in motions], axis=-1)
    o = np.stack([np.broadcast_to(motion[4], p.shape) for motion in motions], axis=-1)
    rotating = np.array([kind == _ROT for kind, *_ in motions])
    arm = p[..., None] - o
    crossed = np.cross(u, arm, axisa=-2, axisb=-2, axisc=-2)
    return np.where(rotating, crossed, u)


def fixed_transforms(structure: Structure, dh: ArrayLike) -> Array:
    """The chain as fixed transforms between joints: base_T_flange(q) = T_0 · J_1(q_1) · T_1 ⋯
    J_n(q_n) · T_n, each joint turning about the z axis of its own frame (J = Rz) or, prismatic,
    sliding along it (J = Tz).

    The form a URDF, Pinocchio or MuJoCo model needs: T_0 places joint 1 in the base frame,
    T_i joint i + 1 in joint i's frame, T_n the flange in joint n's frame.

    Args:
        structure: What the table means.
        dh: One parameter table, shape (4, n), or a stack of them, (k, 4, n).

    Returns:
        T_0..T_n, shape (n + 1, 4, 4), or (k, n + 1, 4, 4).
    """
    return chain_transforms(structure, *joint_placements(structure, dh))


def chain_transforms(structure: Structure, pre: Array, post: Array) -> Array:
    """:func:`fixed_transforms` from the joints' placements (:func:`joint_placements`) when
    the caller has them already, shape (..., n + 1, 4, 4)."""
    n = structure.n_joints
    transforms = [structure.base @ pre[..., 0, :, :]]
    transforms += [post[..., i, :, :] @ pre[..., i + 1, :, :] for i in range(n - 1)]
    transforms.append(post[..., -1, :, :] @ structure.tool)
    return np.stack(transforms, axis=-3)


def joint_placements(structure: Structure, dh: ArrayLike) -> tuple[Array, Array]:
    """Each joint's link transform split where its variable acts: A_i(q) = pre_i · J(q_i) ·
    post_i, J = Rz for a revolute joint, Tz for a prismatic one.

    ``post_i`` places link frame i (the frame :func:`frames` gives, which turns with joint i) in
    the joint's own turning frame: where a link's centre of mass, given in its link frame, sits
    in a body that carries the joint.

    Args:
        structure: What the table means.
        dh: One parameter table, shape (4, n), or a stack of them, (k, 4, n).

    Returns:
        ``(pre, post)``, each shape (n, 4, 4), or (k, n, 4, 4).
    """
    table = np.asarray(dh, dtype=np.float64)
    n = structure.n_joints
    if table.shape[-2:] != (4, n) or table.ndim not in (2, 3):
        raise ValueError(f"dh: shape {table.shape}, expected (4, {n}) or (k, 4, {n})")
    # One table's entries as Python floats, a stack's as arrays over its tables (k,).
    entries = table if table.ndim == 2 else np.moveaxis(table, 0, -1)
    pre, post = [], []
    for i, (kind, joint_type) in enumerate(zip(structure.parametrisation,
                                               structure.joint_types, strict=True)):
        motions = joint_motions(kind, joint_type)
        joint_at = next(index for index, motion in enumerate(motions) if motion[3])
        pre.append(_compose(motions[:joint_at], entries[:, i]))
        # The joint's own offset moves with q: Rz(q + θ) = Rz(q) · Rz(θ), Tz(q + d) likewise.
        post.append(_compose(motions[joint_at:], entries[:, i]))
    return np.stack(pre, axis=-3), np.stack(post, axis=-3)


def _compose(motions: tuple[tuple[int, int, int, bool], ...], slots: Array) -> Array:
    """The product of the elementary motions, (4, 4), or (k, 4, 4) for slots (4, k) of k
    tables: each applied to the columns of the product so far (T · Tr moves column 4 along
    one axis; T · Rot turns two columns), on Python floats for one table — an identity and a
    4×4 product per motion were a fifth of building a MuJoCo twin — and on arrays over the
    tables for a stack (a warm-up's rows, each on its own table)."""
    one = slots.ndim == 1
    cos, sin = (math.cos, math.sin) if one else (np.cos, np.sin)
    unit, nil = (1.0, 0.0) if one else (np.ones(slots.shape[1:]), np.zeros(slots.shape[1:]))
    columns = [[unit, nil, nil, nil], [nil, unit, nil, nil], [nil, nil, unit, nil],
               [nil, nil, nil, unit]]
    for kind, axis, slot, _ in motions:
        if kind == _TRANS:
            if slot != NO_SLOT:  # a prismatic Hayati joint's slide: no fixed part
                along, by = columns[axis], float(slots[slot]) if one else slots[slot]
                columns[3] = [t + a * by for t, a in zip(columns[3], along, strict=True)]
        else:
            c, s = cos(slots[slot]), sin(slots[slot])
            j, k = (axis + 1) % 3, (axis + 2) % 3
            first, second = columns[j], columns[k]
            columns[j] = [a * c + b * s for a, b in zip(first, second, strict=True)]
            columns[k] = [b * c - a * s for a, b in zip(first, second, strict=True)]
    product = np.array(columns)  # (column, row) or (column, row, k)
    return product.T if one else np.moveaxis(product, -1, 0).swapaxes(-1, -2)


def rigid_transform(xyz_m: ArrayLike, rpy_rad: ArrayLike) -> Array:
    """The 4×4 transform of a URDF-style origin: translation xyz (m), then the fixed-axis
    roll–pitch–yaw rotation R = Rz(yaw) · Ry(pitch) · Rx(roll) (rad)."""
    roll, pitch, yaw = (float(v) for v in np.asarray(rpy_rad, dtype=np.float64))
    cr, sr, cp, sp, cy, sy = (np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch),
                              np.cos(yaw), np.sin(yaw))
    transform = np.eye(4)
    transform[:3, :3] = [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                         [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                         [-sp, cp * sr, cp * cr]]
    transform[:3, 3] = np.asarray(xyz_m, dtype=np.float64)
    return transform


def xyz_rpy(transform: ArrayLike) -> tuple[Array, Array]:
    """Inverse of :func:`rigid_transform`: ``(xyz (3,) m, rpy (3,) rad)``, pitch in
    [−π/2, π/2]. At pitch ±π/2 (gimbal lock) only roll ∓ yaw is defined: yaw is set to 0, so
    the rotation is still reproduced exactly."""
    matrix = np.asarray(transform, dtype=np.float64)
    rotation = matrix[:3, :3]
    pitch = np.arctan2(-rotation[2, 0], np.hypot(rotation[0, 0], rotation[1, 0]))
    if np.hypot(rotation[0, 0], rotation[1, 0]) > 1e-9:
        roll = np.arctan2(rotation[2, 1], rotation[2, 2])
        yaw = np.arctan2(rotation[1, 0], rotation[0, 0])
    else:  # cos(pitch) ≈ 0: R = Rz(yaw) · Ry(±π/2) · Rx(roll) depends on roll ∓ yaw alone
        yaw = 0.0
        roll = np.arctan2(rotation[0, 1], rotation[1, 1]) if pitch > 0 \
            else np.arctan2(-rotation[0, 1], rotation[1, 1])
    return np.array(matrix[:3, 3], dtype=np.float64), np.array([roll, pitch, yaw])
