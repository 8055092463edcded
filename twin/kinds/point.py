"""Fixed points: the measured point was brought to the same unknown place on several rows.

A ball on the tool set into the sockets of a fixture, a pointer touched to fixed marks: a row
says only which place (a name) the measured point was at.

Such data cannot see a turn of the robot and every fixed point together about joint 1's axis, a
shift along it, nor — without a known distance — a common scale of every length (robot, tool
point and fixed points). The shift is an exact null direction of the Jacobian; the turn and the
scale are not (they rotate or stretch the residuals, a change of the size of the noise) although
the cost is exactly flat along them: :meth:`Point.symmetries` gives them to the identifiability
and the Cramér–Rao bound as the known gauge group. For pose i at place j, three rows
``r_i = p_i − (P_j + δP_j)``, with P_j the rig's :attr:`~twin.rig.Rig.points_m` and δP_j the
correction of group ``points``; then one row per known distance between two places,
``w (‖P_a − P_b‖ − D_ab)`` (:attr:`~twin.rig.Rig.distances`), weighted by
:data:`DISTANCE_WEIGHT`: a fixture's spacing is known far better than a ball seats (a ball bar
is certified to a micrometre), so its row counts as if its noise were a tenth of a reading's —
the least-squares fit then holds it nearly exactly, and the Cramér–Rao bound, which takes one σ
for every row, sees the distance as the sharp constraint it is. The distance rows belong to no
pose: every subset of the measurements (training, validation) carries them.

Readings: the labels ``point`` naming each row's place. In a file: a ``point`` column.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import Array, frozen_array
from twin.choices import MAX_POSES
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
    POSE_TEXT,
    Bench,
    Captured,
    Fields,
    TargetSetup,
    pose_mm_deg,
    read_target,
    refuse_port,
)
from twin.rig import Distance, Rig
from twin.robot import RobotModel
from twin.units import mm_to_m

if TYPE_CHECKING:
    from twin.model import Model


DISTANCE_WEIGHT = 10.0
"""Weight of a known-distance row against a reading's rows (its noise a tenth of theirs)."""
POINT = "point"
"""The labels of each row's fixed place."""


def point_measurements(q_rad: ArrayLike, point: ArrayLike, *, point_names: Sequence[str] = (),
                       approach: ArrayLike | None = None) -> Measurements:
    """Fixed points: joint angles (m, n), rad, and the index of the place each row's measured
    point was at (m,), with the name of each index if known (approach as
    :func:`twin.kinds.length.length_measurements`)."""
    return Point().labelled(q_rad, point, point_names, approach)


class Point(PlaceKind):
    """Fixed points (:mod:`twin.kinds.point`)."""

    name = "point"
    place = POINT
    what = "fixed points"
    rows_per_pose = 3
    groups = ("points",)
    implied = ("points",)
    labels = (POINT,)
    columns_text = "point"
    flags = (("--distance", "fixed points (the distance between two of them)"),)
    random_poses = False
    measurement_keys = ("sigma_mm", "attachment_mm", "told_attachment_mm")
    scenario_tables = (("fixture", ("sockets_mm", "placements", "touches", "distances")),)

    @staticmethod
    def _points(values: Mapping[str, Array], rig: Rig) -> Array:
        """Every fixed point, shape (..., f, 3), m."""
        if "points" not in values:
            return rig.points_m
        correction = values["points"]
        return np.asarray(rig.points_m + correction.reshape(*correction.shape[:-1], -1, 3),
                          dtype=np.float64)

    def template(self, q_rad: Array, rig: Rig, labels: Mapping[str, NDArray[np.intp]]
                 ) -> Measurements:
        """Rows at the places given (place 0 if none), named as the rig's."""
        places = labels.get(POINT, np.zeros(len(q_rad), dtype=np.intp))
        return point_measurements(q_rad, places, point_names=rig.point_names)

    def residuals(self, at: Measured, values: Mapping[str, Array], data: Measurements,
                  rig: Rig) -> Array:
        """r = point − its place (3 rows per pose), then w (‖P_a − P_b‖ − D) per known
        distance: shape (..., 3m + d), m."""
        points = self._points(values, rig)
        difference = at.position_m - points[..., data.index(POINT), :]
        pairs = rig.distance_index
        spans = np.linalg.norm(points[..., pairs[:, 0], :] - points[..., pairs[:, 1], :],
                               axis=-1)
        batch = difference.shape[:-2]
        return np.concatenate([difference.reshape(*batch, -1),
                               np.broadcast_to(DISTANCE_WEIGHT * (spans - rig.distances_m),
                                               (*batch, len(pairs)))],
                              axis=-1)

    def measure(self, at: Measured, values: Mapping[str, Array], template: Measurements,
                rig: Rig) -> Measurements:
        """The template's rows: the model fits them exactly when the rows of each place put the
        measured point there."""
        return template

    def jacobian(self, at: Measured, values: Mapping[str, Array], data: Measurements,
                 rig: Rig) -> KindJacobian:
        """∂r/∂p = I; ∂r/∂δP_j = −I on the rows of place j; a distance row has ±w u (u the unit
        vector from b to a) on its two places."""
        m = len(data)
        residuals = self.residuals(at, values, data, rig)
        by_group: dict[str, Array] = {}
        if "points" in values:
            f = len(rig.point_names)
            pose_rows = np.zeros((m, 3, f, 3))
            pose_rows[np.arange(m), :, data.index(POINT), :] = -np.eye(3)
            points = self._points(values, rig)
            pairs = rig.distance_index
            span = points[pairs[:, 0]] - points[pairs[:, 1]]
            u = span / np.linalg.norm(span, axis=-1, keepdims=True)
            distance_rows = np.zeros((len(pairs), f, 3))
            distance_rows[np.arange(len(pairs)), pairs[:, 0]] = DISTANCE_WEIGHT * u
            distance_rows[np.arange(len(pairs)), pairs[:, 1]] = -DISTANCE_WEIGHT * u
            by_group["points"] = np.concatenate([pose_rows.reshape(3 * m, 3 * f),
                                                 distance_rows.reshape(len(pairs), 3 * f)])
        return KindJacobian(residuals, np.broadcast_to(np.eye(3), (m, 3, 3)).copy(), by_group)

    def prepare(self, robot: RobotModel, rig: Rig, data: Measurements, noise: Noise
                ) -> tuple[Rig, Measurements]:
        """The rig with the fixed points of the data, each started at the mean of the nominal
        model's measured points of its rows (every row: a start, not a fit).

        Raises:
            InputError: for a known distance between points the data do not name.
        """
        index = data.index(POINT)
        names = data.names(POINT) or tuple(f"point{j + 1}" for j in range(int(index.max()) + 1))
        positions = point_position(robot.structure, robot.dh, data.q_rad, rig.attachment_m)
        counts = np.bincount(index, minlength=len(names))
        starts = np.stack([np.bincount(index, positions[:, k], minlength=len(names))
                           for k in range(3)], axis=1) / np.maximum(counts, 1)[:, None]
        for distance in rig.distances:
            for name in (distance.first, distance.second):
                if name not in names:
                    raise InputError(f"a distance to the point {name!r}", "distances between "
                                     "points the measurements name: " + ", ".join(names),
                                     where="distances")
        return replace(rig, point_names=names, points_m=starts), data

    def describe(self, rig: Rig, data: Measurements) -> str:
        """``6 fixed points``."""
        return f"{len(rig.point_names or data.names(POINT))} fixed points"

    def read_setup(self, tables: Mapping[str, Fields]) -> FixtureSetup:
        """The ball and the fixture (:func:`read_fixture`)."""
        return read_fixture(tables, self.name)

    def draw(self, canvas: Canvas, rig: Rig, data: Measurements, points_m: Array) -> None:
        """The fixed points (``world/fixed_points``, when the rig has them) and, per pose, the
        measured point labelled with its place."""
        names = rig.point_names or data.names(POINT)
        labels = [names[j] if j < len(names) else str(j) for j in data.index(POINT)]
        if rig.point_names:
            canvas.anchors("fixed_points", rig.points_m, list(rig.point_names), MARK_RADIUS_M)
        canvas.marks("measured", points_m, labels, MARK_RADIUS_M)

    def symmetries(self, model: Model, x: Array) -> Array:
        """The turn about joint 1's axis (θ1 with every fixed point) and, without a known
        distance, the scale (every length of the table, the estimated attachment and every
        fixed point about the base origin), as directions of x, shape (p, g)."""
        if not (model.has("points") and model.has("dh")):
            return np.zeros((model.n_params, 0))
        structure = model.robot.structure
        n = structure.n_joints
        origin, axis = structure.base[:3, 3], structure.base[:3, 2]
        points = self._points({"points": model.block(x, "points")}, model.rig)
        turn = np.zeros(model.n_params)
        turn[model.slice("dh").start + 3 * n] = 1.0  # θ1, slot 3 of joint 1
        turn[model.slice("points")] = np.cross(axis, points - origin).ravel()
        directions = [turn]
        scale = None if model.rig.distances else length_scale(model, x)
        if scale is not None:
            scale[model.slice("points")] = (points - origin).ravel()
            directions.append(scale)
        return np.stack(directions, axis=1)


@dataclass(frozen=True)
class FixtureSetup(TargetSetup):
    """A ball fixture in the twin (:class:`twin.kinds.bench.Setup`): its sockets set down at
    several placements; for each socket the arm brings the ball (the measured point) into it
    from ``touches`` different configurations, found on the twin. The ball seats with an
    error of σ per axis.

    Attributes:
        attachment_m: The true ball centre in the flange frame, shape (3,), m.
        attachment_told_m: The ball the calibration is told, shape (3,), m.
        sigma_m: The seating error 1σ per axis, shape (3,), m.
        sockets_m: The fixture's sockets in its own frame, shape (s, 3), m.
        placements: Where the fixture is set down, base frame, shape (P, 4, 4), m.
        touches: Configurations per socket and placement.
        tell_distances: Whether the calibration is told the socket spacings.
    """

    sockets_m: Array
    placements: Array
    touches: int
    tell_distances: bool = True

    def __post_init__(self) -> None:
        super().__post_init__()
        sockets = np.asarray(self.sockets_m, dtype=np.float64).reshape(-1, 3)
        placements = np.asarray(self.placements, dtype=np.float64).reshape(-1, 4, 4)
        if not len(sockets) or not len(placements) or self.touches < 1:
            raise ValueError("fixed points need sockets, placements and touches >= 1")
        object.__setattr__(self, "sockets_m", frozen_array(sockets, sockets.shape, "sockets_m"))
        object.__setattr__(self, "placements",
                           frozen_array(placements, placements.shape, "placements"))

    @property
    def point_names(self) -> tuple[str, ...]:
        """``f<placement>s<socket>`` for every socket of every placement, 1-based."""
        return tuple(f"f{p + 1}s{s + 1}" for p in range(len(self.placements))
                     for s in range(len(self.sockets_m)))

    @property
    def points_m(self) -> Array:
        """Every socket of every placement in the base frame, shape (P·s, 3), m."""
        return np.concatenate([self.sockets_m @ placement[:3, :3].T + placement[:3, 3]
                               for placement in self.placements])

    @property
    def distances(self) -> tuple[Distance, ...]:
        """The spacing of every pair of sockets within each placement (if told)."""
        if not self.tell_distances:
            return ()
        found = []
        names = self.point_names
        count = len(self.sockets_m)
        for p in range(len(self.placements)):
            for a in range(count):
                for b in range(a + 1, count):
                    length = float(np.linalg.norm(self.sockets_m[a] - self.sockets_m[b]))
                    found.append(Distance(names[p * count + a], names[p * count + b], length))
        return tuple(found)

    @property
    def pose_count(self) -> int | None:
        """A pose per touch of every socket of every placement."""
        return len(self.sockets_m) * len(self.placements) * self.touches

    def rigs(self, rng: np.random.Generator) -> tuple[Rig, Rig]:
        """The true sockets; the calibration is told the ball and (if told) the spacings."""
        return (Rig(attachment_m=self.attachment_m, point_names=self.point_names,
                    points_m=self.points_m),
                Rig(attachment_m=self.attachment_told_m, distances=self.distances))

    def capture(self, bench: Bench, rig: Rig, rng: np.random.Generator) -> Captured:
        """Configurations that seat the ball in every socket ``touches`` times (no joint
        jitter: the ball sits where the socket holds it)."""
        q, point = bench.touch(rig.points_m, self.touches, self.sigma_m, rng)
        return Captured(point_measurements(q, point, point_names=rig.point_names),
                        bench.rigid(q), np.zeros(0, dtype=np.intp), 0.0)

def read_fixture(tables: Mapping[str, Fields], name: str) -> FixtureSetup:
    """``[measurement]`` (the ball, its seating σ) and ``[fixture]`` (sockets, placements,
    touches, distances); no ``[cable]``, ``[port]`` or ``[poses]`` count or plan.

    Raises:
        InputError: naming the key that is wrong or does not apply.
    """
    target = read_target(tables, name, frame=False)
    fixture, poses = tables["fixture"], tables["poses"]
    if not fixture.values:
        raise fixture.error("sockets_mm", "no [fixture] table",
                            "[fixture] with fixed points (kind = \"point\") only")
    sockets = mm_to_m(fixture.rows("sockets_mm", 3, expected="a list of [x, y, z] in mm"))
    placements = np.stack([pose_mm_deg(row) for row in fixture.rows(
        "placements", 6, expected=f"a list of {POSE_TEXT}")])
    touches = fixture.integer("touches", 12, minimum=1, maximum=MAX_POSES)
    setup = FixtureSetup(target.attachment_m, target.attachment_told_m, target.sigma_m,
                         sockets, placements, touches, fixture.boolean("distances", True))
    refuse_port(tables, name)
    for key in ("count", "plan"):
        if poses.has(key):
            raise poses.error(key, f"{key} with fixed points",
                              "[fixture] placements and touches (they set the poses)")
    count = setup.pose_count or 0
    if count > MAX_POSES:
        raise fixture.error("touches", f"{touches} touches of {len(setup.points_m)} sockets "
                            f"({count} poses)", f"at most {MAX_POSES} poses in all")
    return setup
