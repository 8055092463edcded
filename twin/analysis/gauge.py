"""Gauge freedoms: the motions of the predicted flange (or measured point) that the data cannot
see, named, and the error against the truth modulo them.

Distances from a port that is itself estimated cannot see a turn of everything about joint 1's
axis or a shift along it (they trade with δθ1 and δd1); a tracker frame estimated freely absorbs
the same; fixed points without a known distance cannot see the scale; an estimated attachment
leaves the flange free to slide in its own frame under the measured point; and one measured
point off the flange, even a known one, cannot see the flange turn about it (a turn about an
axis parallel to joint 6's through the point trades with θ6, a6, d6, α6); and distances from
one known port cannot see the arm turn about an axis through that port, which a chain that can
carry its arm sideways represents (a torso lift before a parallel shoulder: its a1 and θ1 with
the shoulder's θ2 turn the arm about the vertical through the port). Each is a direction
of the null space of the measurement Jacobian that moves the predicted point: such data define
the robot's positions only up to that motion, and a comparison with the truth in the base frame
measures partly the frame, not the calibration.

How the motions are found and named:

1. The null space N (p, r) of the measurement Jacobian at the identified unknowns
   (:mod:`twin.analysis.identifiability`) is carried to the predicted points over the workspace
   poses,
   M = ∂p/∂x · N (3k, r). Columns that move nothing (θ6 of a flange centre, d2 − d3) drop out:
   singular values of M below :data:`MOVES_RTOL` of the largest column norm of ∂p/∂x do not count.
2. Each candidate motion (:data:`MOTIONS`: rotations about and shifts along joint 1's axis and
   the other base axes, a scale about the base origin, shifts of the flange along its own axes;
   rotations about the base axes through the first port, for cable lengths)
   is a vector field over the same points; it is *unobservable* when it lies in the span of M
   (relative distance below :data:`MATCH_RTOL`). Then the other directions of the flange's own
   frame along which a shift lies in the span: one measured point off the flange leaves the
   flange free to turn about it, which moves the flange centre along such a direction. What no
   candidate explains is counted as unnamed motion.

The error modulo the motions (:func:`gauge_free_rms`) applies the named motions exactly (a
finite rotation about an axis, not its linearisation) and the unnamed part linearly, with the
parameters that bring the predicted points closest to the truth (Gauss–Newton with the
motions' analytic Jacobian).
The Cramér–Rao bound (:mod:`twin.analysis.uncertainty`) leaves the same motions out, so it is the
bound of this error.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from twin.analysis.linearisation import chain_jacobian
from twin.arrays import Array
from twin.geometry.rigid import exp_rotation, right_jacobian
from twin.model import Model

MOVES_RTOL = 1e-6
"""A null direction moves the points when its motion's singular value exceeds this fraction of
the largest column norm of ∂p/∂x (1e-6 m per metre or radian of an unknown: round-off is 1e-16)."""
MATCH_RTOL = 1e-4
"""A candidate motion is unobservable when its distance from the span of the null motions is
below this fraction of its norm."""
FIT_ITERATIONS = 10
"""Most Gauss–Newton steps of :func:`gauge_free_rms` (two or three reach the minimum)."""
FIT_RTOL = 1e-6
""":func:`gauge_free_rms` stops when a step changes the distances by less than this fraction of
them: a Gauss–Newton step lowers their squared sum by the square of its change (the step
leaves them orthogonal to it), so what is left is below 1e-12 of it."""
ROTATION, SHIFT, SCALE, FLANGE_SHIFT = "rotation", "shift", "scale", "flange shift"
PIN_BASE = ("a reference in the base frame: a port or tracker frame measured in it (no "
            "--estimate-port, or --estimate-port NAME for the others; no --estimate-base), or "
            "θ1 and d1 held at the nominal (lm-base)")
PIN_SCALE = "a known distance between two fixed points (--distance A,B=MM)"
PIN_FLANGE = ("a measured attachment (--attachment X,Y,Z without --estimate-attachment); the "
              "measured point itself is identified")
PIN_TURN = ("a second measured point on the tool (the flange turns about the measured point "
            "unseen); the measured point itself is identified")
PIN_PORT = ("a second port (--port NAME=X,Y,Z and a port column: distances from one point "
            "cannot see a turn about it) or a laser tracker")
ORIGIN, PORT = "origin", "port"
"""What a rotation turns about: frame 0's origin, or the first port."""


class Motion(NamedTuple):
    """A candidate motion of the predicted points."""

    name: str
    """What people read, e.g. ``rotation about joint 1's axis``."""
    kind: str
    """:data:`ROTATION`, :data:`SHIFT`, :data:`SCALE` or :data:`FLANGE_SHIFT`."""
    axis: int
    """The axis (0, 1, 2: x, y, z) of frame 0, or -1 for a flange shift."""
    pin: str
    """How to pin it."""
    direction: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """A flange shift's direction in the flange frame, unit."""
    through: str = ORIGIN
    """A rotation's centre: :data:`ORIGIN` (frame 0's) or :data:`PORT` (the first port's)."""


MOTIONS = (
    Motion("rotation about joint 1's axis", ROTATION, 2, PIN_BASE),
    Motion("shift along joint 1's axis", SHIFT, 2, PIN_BASE),
    Motion("rotation about the base x axis", ROTATION, 0, PIN_BASE),
    Motion("rotation about the base y axis", ROTATION, 1, PIN_BASE),
    Motion("shift along the base x axis", SHIFT, 0, PIN_BASE),
    Motion("shift along the base y axis", SHIFT, 1, PIN_BASE),
    Motion("scale about the base origin", SCALE, 0, PIN_SCALE),
    Motion("shift of the flange along its own x axis", FLANGE_SHIFT, -1, PIN_FLANGE,
           (1.0, 0.0, 0.0)),
    Motion("shift of the flange along its own y axis", FLANGE_SHIFT, -1, PIN_FLANGE,
           (0.0, 1.0, 0.0)),
    Motion("shift of the flange along its own z axis", FLANGE_SHIFT, -1, PIN_FLANGE,
           (0.0, 0.0, 1.0)),
    Motion("rotation about the vertical through the port", ROTATION, 2, PIN_PORT,
           through=PORT),
    Motion("rotation about the base x axis through the port", ROTATION, 0, PIN_PORT,
           through=PORT),
    Motion("rotation about the base y axis through the port", ROTATION, 1, PIN_PORT,
           through=PORT),
)
"""Candidate motions, in the order they are named. Base axes are those of the chain's frame 0
(joint 1 turns about its z axis). Shifts of the flange along other directions of its own frame
come after (:func:`_flange_shifts`)."""


class Gauge(NamedTuple):
    """The motions of the predicted points that the data cannot see."""

    motions: tuple[Motion, ...]
    """The named unobservable motions."""
    unnamed: Array
    """Unobservable motions no candidate explains, as fields over the points, shape (3k, u)."""
    points_m: Array
    """The predicted points the motions were found at, shape (k, 3), m."""
    flange_rotations: Array | None
    """The flange's rotation at each of those poses, shape (k, 3, 3); None when no motion
    moves the points (nothing to turn them by)."""
    origin_m: Array
    """Frame 0's origin, shape (3,), m."""
    axes: Array
    """Frame 0's axes as columns, shape (3, 3)."""
    point_in_flange_m: Array
    """The measured point in the flange frame, shape (3,), m."""
    port_m: Array | None = None
    """The first port, base frame, shape (3,), m; None without one."""

    def centre(self, motion: Motion) -> Array:
        """The point a rotation turns about, base frame, shape (3,), m."""
        if motion.through == PORT:
            assert self.port_m is not None
            return self.port_m
        return self.origin_m

    @property
    def names(self) -> tuple[str, ...]:
        """Every unobservable motion, the unnamed ones counted."""
        extra = self.unnamed.shape[1]
        return tuple(motion.name for motion in self.motions) + (
            (f"{extra} other motion{'s' if extra > 1 else ''}",) if extra else ())

    @property
    def pins(self) -> tuple[str, ...]:
        """How to pin them, each way once."""
        return tuple(dict.fromkeys(motion.pin for motion in self.motions))

    def describe(self) -> str:
        """One line: ``rotation about joint 1's axis, shift along joint 1's axis``, or ``none``.
        """
        return ", ".join(self.names) or "none"


def _field(motion: Motion, points: Array, rotations: Array, origin: Array, axes: Array) -> Array:
    """The motion's velocity at every point, shape (k, 3); a rotation turns about ``origin``."""
    if motion.kind == ROTATION:
        return np.cross(axes[:, motion.axis], points - origin)
    if motion.kind == SHIFT:
        return np.broadcast_to(axes[:, motion.axis], points.shape)
    if motion.kind == SCALE:
        return points - origin
    return rotations @ np.asarray(motion.direction)


def _flange_shifts(span: Array, rotations: Array, named: list[Array], point_in_flange: Array
                   ) -> list[Motion]:
    """Shifts of the flange along fixed directions of its own frame whose field lies in the
    span of the null motions (3k, r) and is not a combination of the ``named`` fields; with a
    measured point off the flange, what they are is the flange turning about it."""
    # The fields R_i d of d = x, y, z are orthogonal with norm √k: an orthonormal basis.
    basis = np.stack([rotations[:, :, axis].ravel() for axis in range(3)], axis=1)
    basis /= np.linalg.norm(basis, axis=0)
    outside = basis - span @ (span.T @ basis)
    # Thin: a full U of the 3k rows was 0.16 s of a report (k = 1000 workspace poses).
    _, s, vt = np.linalg.svd(outside, full_matrices=False)
    off = bool(np.linalg.norm(point_in_flange) > 0)
    found = []
    for direction in vt[s < MATCH_RTOL]:
        vector = basis @ direction
        if _within(vector, named, 1.0):
            continue
        shown = ", ".join(f"{c:.2f}" for c in direction)
        found.append(Motion(
            f"shift of the flange along ({shown}) in its own frame"
            + (" (it turns about the measured point)" if off else ""), FLANGE_SHIFT, -1,
            PIN_TURN if off else PIN_FLANGE,
            (float(direction[0]), float(direction[1]), float(direction[2]))))
    return found


def _within(vector: Array, fields: list[Array], norm: float) -> bool:
    """Whether ``vector`` is already a combination of the motions named before it (a turn of
    the flange about the measured point is a shift of the flange when all three are named)."""
    if not fields:
        return False
    named = np.stack(fields, axis=1)
    rest = vector - named @ np.linalg.lstsq(named, vector, rcond=None)[0]
    return bool(np.linalg.norm(rest) < MATCH_RTOL * norm)


def unobservable_motions(model: Model, x: ArrayLike, null_space: ArrayLike, q_rad: ArrayLike,
                         *, measured: bool = False) -> Gauge:
    """The motions of the flange centres (or measured points) at poses q that the data cannot
    see.

    Args:
        model: The fitted model.
        x: Identified unknowns, shape (p,).
        null_space: Null directions of the measurement Jacobian at x, shape (p, r), in the units
            of x (:attr:`twin.analysis.identifiability.Identifiability.null_space`).
        q_rad: Poses the motions are evaluated at (the workspace), shape (k, n), rad.
        measured: The measured point (attachment) instead of the flange centre.
    """
    x = np.asarray(x, dtype=np.float64)
    data = model.poses(q_rad)
    points = model.positions(x, data) if measured else model.flange_positions(x, data)
    base = model.robot.structure.base
    origin, axes = base[:3, 3], base[:3, :3]
    port = model.kind.pivot(model.rig)
    gauge = Gauge((), np.zeros((points.size, 0)), points, None, origin, axes, model.point(x),
                  port)
    null = np.asarray(null_space, dtype=np.float64)
    if not null.shape[1]:
        return gauge
    jacobian = chain_jacobian(model, x, data, measured=measured)
    moves = (jacobian @ null).reshape(points.size, -1)
    largest = float(np.max(np.linalg.norm(jacobian.reshape(points.size, -1), axis=0)))
    u, s, _ = np.linalg.svd(moves, full_matrices=False)
    span = u[:, s > MOVES_RTOL * largest]
    if not span.shape[1]:
        return gauge
    rotations = model.flange_rotations(x, data)
    gauge = gauge._replace(flange_rotations=rotations)
    named: list[Motion] = []
    fields: list[Array] = []
    for motion in MOTIONS:
        if motion.through == PORT and port is None:
            continue
        vector = _field(motion, points, rotations, gauge.centre(motion), axes).ravel()
        norm = float(np.linalg.norm(vector))
        outside = vector - span @ (span.T @ vector)
        if np.linalg.norm(outside) < MATCH_RTOL * norm and not _within(vector, fields, norm):
            named.append(motion)
            fields.append(vector)
    for motion in _flange_shifts(span, rotations, fields, gauge.point_in_flange_m):
        named.append(motion)
        fields.append(_field(motion, points, rotations, origin, axes).ravel())
    explained = np.stack(fields, axis=1) if fields else np.zeros((points.size, 0))
    rest = span - explained @ np.linalg.lstsq(explained, span, rcond=None)[0] if fields \
        else span
    u_rest, s_rest, _ = np.linalg.svd(rest, full_matrices=False)
    unnamed = u_rest[:, s_rest > MATCH_RTOL]
    return gauge._replace(motions=tuple(named), unnamed=unnamed)


class _Moved(NamedTuple):
    """The named motions of some parameters, summed by kind, and the points they move."""

    turn: Array
    """Rotation about frame 0's origin, R = Exp(φ), shape (3, 3)."""
    turn_vector: Array
    """Its rotation vector φ, shape (3,), rad."""
    scale: float
    """The scale about the origin."""
    before_port: Array
    """The points turned, scaled and shifted (and their flange shifted), shape (k, 3), m."""
    port_turn: Array | None
    """Rotation about the first port, shape (3, 3); None when no motion turns about it."""
    port_vector: Array
    """Its rotation vector, shape (3,), rad."""


def _motions(gauge: Gauge, parameters: Array) -> _Moved:
    """What the named motions with ``parameters`` (one per named motion, then one per
    unnamed) do, before the turn about the port and the unnamed motions."""
    points, origin, axes = gauge.points_m, gauge.origin_m, gauge.axes
    rotation_vector, shift, scale = np.zeros(3), np.zeros(3), 0.0
    flange_shift, about_port = np.zeros(3), np.zeros(3)
    for motion, value in zip(gauge.motions, parameters, strict=False):
        if motion.kind == ROTATION and motion.through == PORT:
            about_port += value * axes[:, motion.axis]
        elif motion.kind == ROTATION:
            rotation_vector += value * axes[:, motion.axis]
        elif motion.kind == SHIFT:
            shift += value * axes[:, motion.axis]
        elif motion.kind == SCALE:
            scale = value
        else:
            flange_shift += value * np.asarray(motion.direction)
    kinds = {(motion.kind, motion.through) for motion in gauge.motions}
    # Exp costs scipy's checks (20 µs): not for a turn no motion makes.
    turn = exp_rotation(rotation_vector) if (ROTATION, ORIGIN) in kinds else np.eye(3)
    moved = origin + (1.0 + scale) * (points - origin) @ turn.T + shift
    if gauge.flange_rotations is not None:
        moved = moved + gauge.flange_rotations @ flange_shift
    port_turn = exp_rotation(about_port) if (ROTATION, PORT) in kinds else None
    return _Moved(turn, rotation_vector, float(scale), moved, port_turn, about_port)


def _finish(gauge: Gauge, moved: _Moved, parameters: Array) -> Array:
    """The points of :func:`_motions` turned about the port and moved by the unnamed motions,
    shape (k, 3), m."""
    points = moved.before_port
    if moved.port_turn is not None:
        assert gauge.port_m is not None  # a motion about the port is named only with one
        points = gauge.port_m + (points - gauge.port_m) @ moved.port_turn.T
    linear = gauge.unnamed @ parameters[len(gauge.motions):]
    return points + linear.reshape(points.shape)


def _moved(gauge: Gauge, parameters: Array) -> Array:
    """The predicted points moved by the gauge's motions with the given parameters (one per
    named motion, then one per unnamed), shape (k, 3): named motions exactly, unnamed ones
    linearly."""
    return _finish(gauge, _motions(gauge, parameters), parameters)


def _moved_jacobian(gauge: Gauge, parameters: Array) -> tuple[Array, Array]:
    """:func:`_moved` (k, 3) and its derivative by the parameters, shape (3k, count), the
    points' rows as ``ravel`` lays them out: a turn's columns through the right Jacobian of
    Exp (Exp(φ + δ) a ≈ Exp(φ) (a + J_r(φ) δ × a))."""
    moved = _motions(gauge, parameters)
    axes, port, port_turn = gauge.axes, gauge.port_m, moved.port_turn
    arm = gauge.points_m - gauge.origin_m
    columns = []
    for motion in gauge.motions:
        if motion.kind == ROTATION and motion.through == PORT:
            assert port is not None and port_turn is not None  # named only with a port
            turning = right_jacobian(moved.port_vector) @ axes[:, motion.axis]
            columns.append(np.cross(turning, moved.before_port - port) @ port_turn.T)
            continue
        if motion.kind == ROTATION:
            turning = right_jacobian(moved.turn_vector) @ axes[:, motion.axis]
            column = (1.0 + moved.scale) * np.cross(turning, arm) @ moved.turn.T
        elif motion.kind == SHIFT:
            column = np.broadcast_to(axes[:, motion.axis], arm.shape)
        elif motion.kind == SCALE:
            column = arm @ moved.turn.T
        else:
            assert gauge.flange_rotations is not None  # a flange shift is named with them
            column = gauge.flange_rotations @ np.asarray(motion.direction)
        columns.append(column if port_turn is None else column @ port_turn.T)
    named = np.stack([column.ravel() for column in columns], axis=1) if columns \
        else np.zeros((arm.size, 0))
    return _finish(gauge, moved, parameters), np.concatenate([named, gauge.unnamed], axis=1)


def gauge_free_rms(gauge: Gauge, true_points_m: ArrayLike) -> float:
    """RMS distance between the predicted points and the true ones after the unobservable
    motions that bring them closest, m (the plain RMS distance when there are none).

    Gauss–Newton on the motions' parameters from zero, with their analytic Jacobian: the
    motions between an identified robot and the truth are micrometres and microradians, so
    the problem is nearly linear and a step or two reach the minimum; it stops when a step
    changes the distances by less than :data:`FIT_RTOL` of them, or after
    :data:`FIT_ITERATIONS` (the distances at any parameters bound the least from above).
    scipy's least_squares on finite differences, which it matches to 1e-12 m, was 13 % of a
    tracker trial.

    Args:
        gauge: The motions, found at the predicted points (:func:`unobservable_motions`).
        true_points_m: The true points at the same poses, shape (k, 3), m.
    """
    truth = np.asarray(true_points_m, dtype=np.float64)
    count = len(gauge.motions) + gauge.unnamed.shape[1]
    if not count:
        return float(np.sqrt(np.mean(np.sum((gauge.points_m - truth) ** 2, axis=1))))
    parameters = np.zeros(count)
    for _ in range(FIT_ITERATIONS):
        moved, jacobian = _moved_jacobian(gauge, parameters)
        difference = (moved - truth).ravel()
        step = np.linalg.lstsq(jacobian, -difference, rcond=None)[0]
        parameters = parameters + step
        if np.linalg.norm(jacobian @ step) <= FIT_RTOL * np.linalg.norm(difference):
            break
    return float(np.sqrt(np.mean(np.sum((_moved(gauge, parameters) - truth) ** 2, axis=1))))
