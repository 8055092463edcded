"""Touches of planes: a touch probe or a dial indicator brought against a flat surface; a row says
only which plane (a name) the measured point — the probe's ball centre — touched.

The planes are unknown (group ``planes``). Plane j is ``n_jᵀ p = d_j``: the normal n_j turned
from the start normal n0_j by two angles a, b about the two axes e1, e2 that lie in the start
plane, ``n = (n0 + tan a · e1 + tan b · e2) / ‖·‖``, and the offset ``d_j = d0_j + δd``. The
calibration starts each plane at the plane fitted (least squares, SVD) to the nominal model's
points of its rows (:class:`PlaneRig`), so the angles are small. For pose i on plane j, one row
``r_i = n_jᵀ p_i − d_j`` (m); then one row per known distance between two parallel planes a and
b (``--distance A,B=MM``: a gauge block's faces), ``w (|d_a − (n_a·n_b) d_b| − D_ab)`` with the
weight of a known distance between fixed points (:data:`twin.kinds.point.DISTANCE_WEIGHT`); then
one row per known angle between two planes (``--angle A,B=DEG``: a square's faces),
``W (∠(n_a, n_b) − φ_ab)`` with the lever :data:`ANGLE_WEIGHT`.

What planes cannot see: a plane is unchanged by any motion within itself, so each plane holds
the measured point along its normal only — three planes whose normals span the space are the
least for a point; the placement of the planes as a whole about joint 1's axis and along it
(a turn and a shift of everything, exact null directions of the Jacobian); and, without a known
distance, a common scale of every length (robot, tool point and plane offsets), which
:meth:`Plane.symmetries` gives the identifiability and the Cramér–Rao bound as the known gauge.
A known angle fixes no length (the scale stays unseen without a distance): it ties two planes'
tilts together, so the touches of each tell on the other's — one less free tilt per angle.
The ball's radius is part of every offset (the ball's centre touches a plane offset by it).

Readings: the labels ``plane`` naming each row's plane. In a file: a ``plane`` column.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import Array, frozen_array, read_only
from twin.dataset import Measurements
from twin.errors import InputError
from twin.geometry.kinematics import point_position
from twin.kinds.base import (
    MARK_RADIUS_M,
    Canvas,
    KindJacobian,
    Measured,
    Noise,
    PlaceKind,
    length_scale,
)
from twin.kinds.bench import (
    Bench,
    Captured,
    Fields,
    TargetSetup,
    read_target,
    refuse_port,
)
from twin.kinds.point import DISTANCE_WEIGHT
from twin.report.display import mm
from twin.rig import Angle, Distance, Part, Rig
from twin.robot import RobotModel
from twin.units import m_to_mm, mm_to_m

if TYPE_CHECKING:
    from twin.model import Model

PLANE = "plane"
"""The labels of each row's plane."""
GROUP = "planes"
"""The unknown group of the planes' corrections."""
PLANE_POINTS = 3
"""The fewest touches of a plane (not on one line) that give it a start."""
COLLINEAR_RTOL = 1e-6
"""Touches whose second singular value is below this of the first lie on one line."""
PARALLEL_COS = float(np.cos(np.deg2rad(1.0)))
"""Planes whose normals are within 1° count as parallel (a scenario tells their distance, and
not their angle)."""
ANGLE_WEIGHT = 1.0
"""A known angle's row (rad) weighs as a reading (m) at the end of this lever, m: its noise is
σ / 1 m rad (5 µrad, about 1″, for a 5 µm probe: a granite square's order)."""


def plane_measurements(q_rad: ArrayLike, plane: ArrayLike, *, plane_names: Sequence[str] = (),
                       approach: ArrayLike | None = None) -> Measurements:
    """Touches of planes: joint angles (m, n), rad, and the index of the plane each row's
    measured point touched (m,), with the name of each index if known."""
    return Plane().labelled(q_rad, plane, plane_names, approach)


def in_plane_axes(normals: Array) -> tuple[Array, Array]:
    """Two unit axes e1, e2 in each plane (normals (k, 3)), with e1 × e2 = n: each (k, 3)."""
    helper = np.where(np.abs(normals[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    first = np.cross(normals, helper)
    first /= np.linalg.norm(first, axis=1, keepdims=True)
    return first, np.cross(normals, first)


@dataclass(frozen=True)
class PlaneRig:
    """What the plane kind keeps in the rig (:attr:`twin.rig.Rig.part`): the planes the
    calibration starts from, ``n0ᵀ p = d0``.

    Attributes:
        names: A name per plane, length k.
        normals: Unit normals, base frame, shape (k, 3).
        offsets_m: Offsets d0 from the base origin along each normal, shape (k,), m.
    """

    names: tuple[str, ...]
    normals: Array
    offsets_m: Array

    def __post_init__(self) -> None:
        k = len(self.names)
        if len(set(self.names)) != k:
            raise ValueError(f"names {self.names!r}: expected distinct names")
        normals = frozen_array(self.normals, (k, 3), "normals")
        if not np.allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-9):
            raise ValueError("normals: expected unit vectors")
        object.__setattr__(self, "normals", normals)
        object.__setattr__(self, "offsets_m", frozen_array(self.offsets_m, (k,), "offsets_m"))

    @cached_property
    def axes(self) -> tuple[Array, Array]:
        """The two unit axes e1, e2 in each plane (:func:`in_plane_axes`), each (k, 3): made
        once, where every evaluation of the planes' residuals and Jacobian made them again
        (six of a Jacobian's eight cross products); read-only, as the normals are."""
        first, second = in_plane_axes(self.normals)
        return read_only(first), read_only(second)

    def places(self, group: str) -> tuple[str, ...]:
        """The planes, for group ``planes``."""
        return self.names if group == GROUP else ()

    def document(self) -> dict[str, Any]:
        """The planes the calibration started from: names, normals and offsets (m), exactly."""
        return {"names": list(self.names), "normals": self.normals.tolist(),
                "offsets_m": self.offsets_m.tolist()}


def plane_part(rig: Rig) -> PlaneRig:
    """The rig's :class:`PlaneRig` (no plane when it has none)."""
    return rig.part if isinstance(rig.part, PlaneRig) else PlaneRig((), np.zeros((0, 3)),
                                                                    np.zeros(0))


def plane_corrections(start: PlaneRig, true: PlaneRig) -> Array:
    """The group ``planes``' values that turn the start planes into the true ones (matched by
    name, each true plane's normal taken on the start's side), shape (3k,): a, b, δd each."""
    first, second = start.axes
    values = np.zeros((len(start.names), 3))
    for j, name in enumerate(start.names):
        k = true.names.index(name)
        normal, offset = true.normals[k], true.offsets_m[k]
        if normal @ start.normals[j] < 0:
            normal, offset = -normal, -offset
        along = normal @ start.normals[j]
        values[j] = (np.arctan(normal @ first[j] / along), np.arctan(normal @ second[j] / along),
                     offset - start.offsets_m[j])
    return values.ravel()


def _planes(values: Mapping[str, Array], part: PlaneRig) -> tuple[Array, Array, Array]:
    """The normals (..., k, 3), offsets (..., k), m, and the unnormalised normals' lengths
    (..., k) of the values' planes."""
    first, second = part.axes
    if GROUP not in values:
        return part.normals, part.offsets_m, np.ones(len(part.names))
    block = values[GROUP].reshape(*values[GROUP].shape[:-1], -1, 3)
    raw = (part.normals + np.tan(block[..., :1]) * first + np.tan(block[..., 1:2]) * second)
    size = np.linalg.norm(raw, axis=-1)
    return raw / size[..., None], part.offsets_m + block[..., 2], size


def _pairs(told: Sequence[Distance | Angle], part: PlaneRig, what: str = "distance"
           ) -> NDArray[np.intp]:
    """The two planes of each known distance (or angle) as indices into the part's names,
    (d, 2)."""
    pairs = []
    for pair in told:
        for name in (pair.first, pair.second):
            if name not in part.names:
                raise InputError(f"a{'n' if what[0] in 'aeiou' else ''} {what} to the plane "
                                 f"{name!r}", f"{what}s between planes the measurements "
                                 "name: " + ", ".join(part.names), where=f"{what}s")
        pairs.append((part.names.index(pair.first), part.names.index(pair.second)))
    return np.array(pairs, dtype=np.intp).reshape(-1, 2)


def _angles(normals: Array, pairs: NDArray[np.intp]) -> tuple[Array, Array]:
    """The angle between the normals of each pair, rad, and its sine, each (..., d)."""
    first, second = normals[..., pairs[:, 0], :], normals[..., pairs[:, 1], :]
    sine = np.linalg.norm(np.cross(first, second), axis=-1)
    return np.arctan2(sine, np.sum(first * second, axis=-1)), sine


def _gaps(normals: Array, offsets: Array, pairs: NDArray[np.intp]) -> Array:
    """d_a − (n_a·n_b) d_b of each pair: the signed distance between parallel planes, (..., d)."""
    cosine = np.sum(normals[..., pairs[:, 0], :] * normals[..., pairs[:, 1], :], axis=-1)
    return np.asarray(offsets[..., pairs[:, 0]] - cosine * offsets[..., pairs[:, 1]],
                      dtype=np.float64)


def _rows(at: Measured, normals: Array, offsets: Array, angle: Array, data: Measurements,
          rig: Rig) -> Array:
    """The rows of :meth:`Plane.residuals` from the planes' normals (..., k, 3) and offsets
    (..., k), m, and the angles between the normals of the known angles' pairs (..., a),
    rad: shape (..., m + d + a), m."""
    index = data.index(PLANE)
    rows = np.sum(normals[..., index, :] * at.position_m, axis=-1) - offsets[..., index]
    pairs = _pairs(rig.distances, plane_part(rig))
    known = DISTANCE_WEIGHT * (np.abs(_gaps(normals, offsets, pairs))
                               - np.array([d.length_m for d in rig.distances]))
    turned = ANGLE_WEIGHT * (angle - np.array([a.angle_rad for a in rig.angles]))
    shape = rows.shape[:-1]
    return np.concatenate([rows, np.broadcast_to(known, (*shape, len(pairs))),
                           np.broadcast_to(turned, (*shape, len(rig.angles)))], axis=-1)


def fit_plane(points_m: Array) -> tuple[Array, float]:
    """The least-squares plane of points (k, 3), m: its unit normal (3,) and offset d, m.

    Raises:
        InputError: for fewer than three points, or points on one line.
    """
    centre = points_m.mean(axis=0)
    _, s, vt = np.linalg.svd(points_m - centre, full_matrices=False)
    if len(points_m) < PLANE_POINTS or s[1] <= COLLINEAR_RTOL * max(s[0], 1e-300):
        raise InputError(f"{len(points_m)} touches on one line" if len(points_m)
                         >= PLANE_POINTS else f"{len(points_m)} touches",
                         f"at least {PLANE_POINTS} touches of each plane, not on one line")
    normal = vt[2] if vt[2] @ centre >= 0 else -vt[2]
    return normal, float(normal @ centre)


class Plane(PlaceKind):
    """Touches of planes (:mod:`twin.kinds.plane`)."""

    name = "plane"
    place = PLANE
    what = "touches of planes"
    rows_per_pose = 1
    groups = (GROUP,)
    implied = (GROUP,)
    labels = (PLANE,)
    columns_text = "plane"
    flags = (("--distance", "touches of planes (the distance between two parallel ones)"),
             ("--angle", "touches of planes (the angle between two of them)"))
    random_poses = False
    measurement_keys = ("sigma_mm", "attachment_mm", "told_attachment_mm")
    scenario_tables = (("planes", ("points_mm", "normals", "touches", "size_mm",
                                   "distances", "angles")),)

    def template(self, q_rad: Array, rig: Rig, labels: Mapping[str, NDArray[np.intp]]
                 ) -> Measurements:
        """Rows on the planes given (plane 0 if none), named as the rig's."""
        planes = labels.get(PLANE, np.zeros(len(q_rad), dtype=np.intp))
        return plane_measurements(q_rad, planes, plane_names=plane_part(rig).names)

    def residuals(self, at: Measured, values: Mapping[str, Array], data: Measurements,
                  rig: Rig) -> Array:
        """r = n·p − d per pose, then w (|d_a − (n_a·n_b) d_b| − D) per known distance, then
        W (∠(n_a, n_b) − φ) per known angle: shape (..., m + d + a), m."""
        part = plane_part(rig)
        normals, offsets, _ = _planes(values, part)
        angle, _ = _angles(normals, _pairs(rig.angles, part, "angle"))
        return _rows(at, normals, offsets, angle, data, rig)

    def measure(self, at: Measured, values: Mapping[str, Array], template: Measurements,
                rig: Rig) -> Measurements:
        """The template's rows: the model fits them when each row's point lies on its
        plane."""
        return template

    def jacobian(self, at: Measured, values: Mapping[str, Array], data: Measurements,
                 rig: Rig) -> KindJacobian:
        """∂r/∂p = n; ∂r/∂(a, b) = pᵀ ∂n/∂(a, b), ∂n/∂a = (I − n nᵀ) e1 sec²a / ‖·‖;
        ∂r/∂δd = −1; a known distance's or angle's row through its two planes."""
        part = plane_part(rig)
        normals, offsets, size = _planes(values, part)
        angle_pairs = _pairs(rig.angles, part, "angle")
        angle, sine = _angles(normals, angle_pairs)
        index = data.index(PLANE)
        m, k = len(data), len(part.names)
        by_group: dict[str, Array] = {}
        if GROUP in values:
            turns = self._normal_derivatives(values[GROUP], normals, size, part)  # (k, 3, 2)
            pose_rows = np.zeros((m, k, 3))
            pose_rows[np.arange(m), index, :2] = np.einsum("mi,mij->mj", at.position_m,
                                                           turns[index])
            pose_rows[np.arange(m), index, 2] = -1.0
            by_group[GROUP] = np.concatenate(
                [pose_rows.reshape(m, 3 * k),
                 self._distance_rows(normals, offsets, turns, _pairs(rig.distances, part), k),
                 self._angle_rows(normals, turns, angle_pairs, sine, k)])
        # The rows from the normals and angles made here (residuals() made them again: a
        # quarter of the Jacobian).
        return KindJacobian(_rows(at, normals, offsets, angle, data, rig),
                            normals[index][:, None, :], by_group)

    @staticmethod
    def _normal_derivatives(block: Array, normals: Array, size: Array, part: PlaneRig
                            ) -> Array:
        """∂n/∂(a, b) of every plane, shape (k, 3, 2)."""
        first, second = part.axes
        angles = block.reshape(-1, 3)[:, :2]
        across = np.eye(3) - normals[:, :, None] * normals[:, None, :]
        axes = np.stack([first, second], axis=-1) / np.cos(angles[:, None, :]) ** 2
        return np.asarray(across @ axes / size[:, None, None], dtype=np.float64)

    @staticmethod
    def _distance_rows(normals: Array, offsets: Array, turns: Array, pairs: NDArray[np.intp],
                       k: int) -> Array:
        """∂ of each known distance's row w.r.t. the planes' (a, b, δd), shape (d, 3k)."""
        rows = np.zeros((len(pairs), k, 3))
        sign = np.sign(_gaps(normals, offsets, pairs))
        for row, (a, b) in enumerate(pairs):
            cosine = normals[a] @ normals[b]
            rows[row, a, :2] += -offsets[b] * normals[b] @ turns[a]
            rows[row, b, :2] += -offsets[b] * normals[a] @ turns[b]
            rows[row, a, 2] += 1.0
            rows[row, b, 2] += -cosine
            rows[row] *= DISTANCE_WEIGHT * sign[row]
        return rows.reshape(len(pairs), 3 * k)

    @staticmethod
    def _angle_rows(normals: Array, turns: Array, pairs: NDArray[np.intp], sine: Array,
                    k: int) -> Array:
        """∂ of each known angle's row w.r.t. the planes' (a, b, δd), shape (d, 3k), from the
        sines of the angles between the pairs' normals (d,) (:func:`_angles`):
        ∂∠/∂(n_a·n_b) = −1 / sin ∠ (a known angle is 1° to 179°, its sine far from 0)."""
        rows = np.zeros((len(pairs), k, 3))
        for row, (a, b) in enumerate(pairs):
            factor = -ANGLE_WEIGHT / max(float(sine[row]), 1e-12)
            rows[row, a, :2] += factor * normals[b] @ turns[a]
            rows[row, b, :2] += factor * normals[a] @ turns[b]
        return rows.reshape(len(pairs), 3 * k)

    def symmetries(self, model: Model, x: Array) -> Array:
        """Without a known distance, the scale (every length of the table, the estimated
        attachment and every plane's offset), as a direction of x, shape (p, g)."""
        if not (model.has(GROUP) and model.has("dh")) or model.rig.distances:
            return np.zeros((model.n_params, 0))
        scale = length_scale(model, x)
        if scale is None:
            return np.zeros((model.n_params, 0))
        _, offsets, _ = _planes({GROUP: model.block(x, GROUP)}, plane_part(model.rig))
        block = np.zeros((len(offsets), 3))
        block[:, 2] = offsets
        scale[model.slice(GROUP)] = block.ravel()
        return scale[:, None]

    def prepare(self, robot: RobotModel, rig: Rig, data: Measurements, noise: Noise
                ) -> tuple[Rig, Measurements]:
        """The rig with the planes of the data, each started at the plane fitted to the
        nominal model's points of its rows.

        Raises:
            InputError: for a plane touched fewer than three times or along one line, or a
                known distance or angle to a plane the data do not name.
        """
        index = data.index(PLANE)
        names = data.names(PLANE) or tuple(f"plane{j + 1}" for j in range(int(index.max()) + 1))
        positions = point_position(robot.structure, robot.dh, data.q_rad, rig.attachment_m)
        fits = []
        for j, name in enumerate(names):
            try:
                fits.append(fit_plane(positions[index == j]))
            except InputError as exc:
                raise InputError(f"plane {name!r}: {exc.found}", exc.expected) from None
        part = PlaneRig(names, np.array([normal for normal, _ in fits]).reshape(-1, 3),
                        np.array([offset for _, offset in fits]))
        _pairs(rig.distances, part)
        _pairs(rig.angles, part, "angle")
        return replace(rig, part=part), data

    def read_part(self, document: Any) -> Part | None:
        """:meth:`PlaneRig.document` back.

        Raises:
            InputError: for planes that are not named unit normals and offsets.
        """
        try:
            return PlaneRig(tuple(str(name) for name in document["names"]),
                            np.asarray(document["normals"], dtype=np.float64).reshape(-1, 3),
                            np.asarray(document["offsets_m"], dtype=np.float64))
        except (TypeError, ValueError, KeyError):
            raise InputError(f"{document!r}", '{"names": [...], "normals": [[nx, ny, nz], '
                             '...], "offsets_m": [...]}') from None

    def report(self, model: Model, x: Array) -> list[str]:
        """Each identified plane: its normal and offset from the base origin."""
        if not model.has(GROUP):
            return []
        part = plane_part(model.rig)
        normals, offsets, _ = _planes({GROUP: model.block(x, GROUP)}, part)
        return [f"  identified plane {name}: normal ({', '.join(f'{v:.6f}' for v in normal)}), "
                f"{mm(offset, 4)} from the base origin"
                for name, normal, offset in zip(part.names, normals, offsets, strict=True)]

    def describe(self, rig: Rig, data: Measurements) -> str:
        """``40 touches of 3 planes``."""
        return f"{len(data)} touches of {len(plane_part(rig).names or data.names(PLANE))} planes"

    def draw(self, canvas: Canvas, rig: Rig, data: Measurements, points_m: Array) -> None:
        """Each plane at the mean of its touches (``world/planes``) and, per pose, the touching
        point labelled with its plane."""
        index = data.index(PLANE)
        names = plane_part(rig).names or data.names(PLANE) or tuple(
            str(j + 1) for j in range(int(index.max()) + 1))
        centres = np.array([points_m[index == j].mean(axis=0) for j in range(len(names))
                            if np.any(index == j)]).reshape(-1, 3)
        canvas.anchors("planes", centres, [n for j, n in enumerate(names)
                                           if np.any(index == j)], MARK_RADIUS_M)
        canvas.marks("measured", points_m, [names[j] for j in index], MARK_RADIUS_M)

    def read_setup(self, tables: Mapping[str, Fields]) -> PlaneSetup:
        """``[measurement]`` (the probe's ball, its trigger noise) and ``[planes]`` (points,
        normals, touches per plane, the size of the patch touched, whether the distances of
        parallel planes and the angles of the others are told); no ``[cable]`` or ``[port]``,
        no ``[poses]`` count or plan."""
        target = read_target(tables, self.name, frame=False)
        planes, poses = tables["planes"], tables["poses"]
        points = mm_to_m(planes.rows("points_mm", 3, expected="a list of [x, y, z] in mm"))
        normals = planes.rows("normals", 3, expected="a list of [nx, ny, nz], one per point")
        if normals.shape != points.shape or np.any(np.linalg.norm(normals, axis=1) == 0):
            raise planes.error("normals", f"{len(normals)} normals",
                               f"{len(points)} non-zero normals, one per point")
        setup = PlaneSetup(target.attachment_m, target.attachment_told_m, target.sigma_m,
                           points, normals / np.linalg.norm(normals, axis=1, keepdims=True),
                           planes.integer("touches", 12, minimum=PLANE_POINTS, maximum=1000),
                           float(mm_to_m(planes.number("size_mm", 100.0, minimum=1.0))),
                           planes.boolean("distances", True), planes.boolean("angles", False))
        refuse_port(tables, self.name)
        for key in ("count", "plan"):
            if poses.has(key):
                raise poses.error(key, f"{key} with touches of planes",
                                  "[planes] touches (they set the poses)")
        return setup


@dataclass(frozen=True)
class PlaneSetup(TargetSetup):
    """Planes in the twin (:class:`twin.kinds.bench.Setup`): each touched ``touches`` times at
    points drawn uniformly on a square patch around its point, from configurations found on
    the twin; the probe triggers with an error of σ per axis (along the normal, σ of the
    reading).

    Attributes:
        attachment_m: The true probe ball centre in the flange frame, shape (3,), m.
        attachment_told_m: The ball the calibration is told, shape (3,), m.
        sigma_m: The trigger error 1σ per axis, shape (3,), m.
        points_m: A point of each plane, base frame, shape (k, 3), m.
        normals: Each plane's unit normal, base frame, shape (k, 3).
        touches: Touches per plane.
        size_m: The side of the square patch of each plane that is touched, m.
        tell_distances: Whether the calibration is told the distances of parallel planes.
        tell_angles: Whether it is told the angle between every two planes not parallel.
    """

    points_m: Array
    normals: Array
    touches: int
    size_m: float
    tell_distances: bool = True
    tell_angles: bool = False

    def __post_init__(self) -> None:
        super().__post_init__()
        points = np.asarray(self.points_m, dtype=np.float64).reshape(-1, 3)
        if not len(points) or self.touches < PLANE_POINTS:
            raise ValueError(f"planes need points and touches >= {PLANE_POINTS}")
        object.__setattr__(self, "points_m", frozen_array(points, points.shape, "points_m"))
        normals = frozen_array(self.normals, points.shape, "normals")
        if not np.allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-9):
            raise ValueError("normals: expected unit vectors")
        object.__setattr__(self, "normals", normals)

    @property
    def names(self) -> tuple[str, ...]:
        """``plane1``…"""
        return tuple(f"plane{j + 1}" for j in range(len(self.points_m)))

    @property
    def part(self) -> PlaneRig:
        """The true planes."""
        return PlaneRig(self.names, self.normals,
                        np.sum(self.normals * self.points_m, axis=1))

    @property
    def distances(self) -> tuple[Distance, ...]:
        """The distance of every pair of parallel planes (if told)."""
        if not self.tell_distances:
            return ()
        part, found = self.part, []
        for a in range(len(part.names)):
            for b in range(a + 1, len(part.names)):
                if abs(part.normals[a] @ part.normals[b]) >= PARALLEL_COS:
                    gap = _gaps(part.normals, part.offsets_m, np.array([[a, b]]))[0]
                    found.append(Distance(part.names[a], part.names[b], float(abs(gap))))
        return tuple(found)

    @property
    def angles(self) -> tuple[Angle, ...]:
        """The angle between every two planes not parallel (if told)."""
        if not self.tell_angles:
            return ()
        part = self.part
        pairs = np.array([(a, b) for a in range(len(part.names))
                          for b in range(a + 1, len(part.names))
                          if abs(part.normals[a] @ part.normals[b]) < PARALLEL_COS],
                         dtype=np.intp).reshape(-1, 2)
        return tuple(Angle(part.names[a], part.names[b], float(angle))
                     for (a, b), angle in zip(pairs, _angles(part.normals, pairs)[0],
                                              strict=True))

    @property
    def pose_count(self) -> int | None:
        """A pose per touch of every plane."""
        return len(self.points_m) * self.touches

    def rigs(self, rng: np.random.Generator) -> tuple[Rig, Rig]:
        """The true planes; the calibration is told the ball and (if told) the distances of
        parallel planes and the angles of the others."""
        return (Rig(attachment_m=self.attachment_m, part=self.part),
                Rig(attachment_m=self.attachment_told_m, distances=self.distances,
                    angles=self.angles))

    def capture(self, bench: Bench, rig: Rig, rng: np.random.Generator) -> Captured:
        """Configurations that bring the ball to ``touches`` points drawn on each plane's
        patch (no joint jitter: the probe triggers where it touches)."""
        first, second = in_plane_axes(self.normals)
        spread = rng.uniform(-0.5, 0.5, (len(self.points_m), self.touches, 2)) * self.size_m
        places = (self.points_m[:, None] + spread[..., :1] * first[:, None]
                  + spread[..., 1:] * second[:, None]).reshape(-1, 3)
        q, place = bench.touch(places, 1, self.sigma_m, rng)
        return Captured(plane_measurements(q, place // self.touches, plane_names=self.names),
                        bench.rigid(q), np.zeros(0, dtype=np.intp), 0.0)

    def truth(self, rig: Rig) -> dict[str, Any]:
        """``planes``: each plane's normal and offset (mm) from the base origin."""
        part = self.part
        return {"planes": {name: {"normal": normal.tolist(), "offset_mm": float(m_to_mm(d))}
                           for name, normal, d in zip(part.names, part.normals, part.offsets_m,
                                                      strict=True)}}
