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
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from twin.arrays import Array
from twin.dataset import Measurements
from twin.kinds.base import KindJacobian
from twin.rig import Rig

if TYPE_CHECKING:
    from twin.model import Model


DISTANCE_WEIGHT = 10.0
"""Weight of a known-distance row against a reading's rows (its noise a tenth of theirs)."""
ORIGIN_TOL_M = 1e-12
"""A chain's fixed base or tool translation shorter than this counts as none (scale is then a
symmetry: nothing of fixed length is left)."""


class Point:
    """Fixed points (:mod:`twin.kinds.point`)."""

    name = "point"
    rows_per_pose = 3
    groups: tuple[str, ...] = ("points",)

    @staticmethod
    def _points(values: Mapping[str, Array], rig: Rig) -> Array:
        """Every fixed point, shape (..., f, 3), m."""
        if "points" not in values:
            return rig.points_m
        correction = values["points"]
        return np.asarray(rig.points_m + correction.reshape(*correction.shape[:-1], -1, 3),
                          dtype=np.float64)

    def residuals(self, positions: Array, values: Mapping[str, Array], data: Measurements,
                  rig: Rig) -> Array:
        """r = point − its place (3 rows per pose), then w (‖P_a − P_b‖ − D) per known
        distance: shape (..., 3m + d), m."""
        assert data.point is not None
        points = self._points(values, rig)
        difference = positions - points[..., data.point, :]
        pairs = rig.distance_index
        spans = np.linalg.norm(points[..., pairs[:, 0], :] - points[..., pairs[:, 1], :],
                               axis=-1)
        batch = difference.shape[:-2]
        return np.concatenate([difference.reshape(*batch, -1),
                               np.broadcast_to(DISTANCE_WEIGHT * (spans - rig.distances_m),
                                               (*batch, len(pairs)))],
                              axis=-1)

    def measure(self, positions: Array, values: Mapping[str, Array], q_rad: Array, rig: Rig,
                port: NDArray[np.intp] | None = None, point: NDArray[np.intp] | None = None
                ) -> Measurements:
        """Rows at the places ``point`` (place 0 if None): the model fits them exactly when the
        rows of each place put the measured point there."""
        index = np.zeros(len(q_rad), dtype=np.intp) if point is None else point
        return Measurements(q_rad, point=index, point_names=rig.point_names)

    def jacobian(self, positions: Array, values: Mapping[str, Array], data: Measurements,
                 rig: Rig) -> KindJacobian:
        """∂r/∂p = I; ∂r/∂δP_j = −I on the rows of place j; a distance row has ±w u (u the unit
        vector from b to a) on its two places."""
        assert data.point is not None
        m = len(data)
        residuals = self.residuals(positions, values, data, rig)
        by_group: dict[str, Array] = {}
        if "points" in values:
            f = len(rig.point_names)
            pose_rows = np.zeros((m, 3, f, 3))
            pose_rows[np.arange(m), :, data.point, :] = -np.eye(3)
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
        fixed = max(np.linalg.norm(structure.base[:3, 3]), np.linalg.norm(structure.tool[:3, 3]))
        attachment_fixed = not model.has("attachment") \
            and np.linalg.norm(model.rig.attachment_m) > ORIGIN_TOL_M
        if not model.rig.distances and fixed < ORIGIN_TOL_M and not attachment_fixed:
            scale = np.zeros(model.n_params)
            scale[model.slice("dh")] = np.where(structure.is_length, model.table(x), 0.0).ravel()
            if model.has("attachment"):
                scale[model.slice("attachment")] = model.point(x)
            scale[model.slice("points")] = (points - origin).ravel()
            directions.append(scale)
        return np.stack(directions, axis=1)
