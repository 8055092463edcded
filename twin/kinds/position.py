"""3-D positions from a laser tracker: the measured point, seen in the tracker's frame.

For pose i with the measured point at p_i in the base frame, three rows
``r_i = R_c (R_0 p_i + t_0) + t_c − y_i``: ``(R_0, t_0)`` the rig's
:attr:`~twin.rig.Rig.base_in_tracker`, ``(R_c, t_c)`` the correction of group ``base``
(:mod:`twin.unknowns.tracker`; none without it), y_i the tracker's reading.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from twin.arrays import Array
from twin.dataset import Measurements
from twin.geometry.rigid import rotation, rotation_derivatives
from twin.kinds.base import KindJacobian, no_symmetries
from twin.rig import Rig


class Position:
    """Tracker positions (:mod:`twin.kinds.position`)."""

    name = "position"
    symmetries = staticmethod(no_symmetries)
    rows_per_pose = 3
    groups: tuple[str, ...] = ("base",)

    @staticmethod
    def _in_tracker(positions: Array, values: Mapping[str, Array], rig: Rig) -> Array:
        """The points in the tracker frame, shape (..., m, 3), m."""
        nominal = rig.base_in_tracker
        seen = positions @ nominal[:3, :3].T + nominal[:3, 3]
        if "base" not in values:
            return np.asarray(seen, dtype=np.float64)
        correction = values["base"]
        turned = np.einsum("...ij,...mj->...mi", rotation(correction[..., 3:]), seen)
        return np.asarray(turned + correction[..., None, :3], dtype=np.float64)

    def residuals(self, positions: Array, values: Mapping[str, Array], data: Measurements,
                  rig: Rig) -> Array:
        """r = tracker point − reading, shape (..., 3m), m: x, y, z of pose 1, then pose 2…"""
        assert data.position_m is not None
        difference = self._in_tracker(positions, values, rig) - data.position_m
        return np.asarray(difference.reshape(*difference.shape[:-2], -1), dtype=np.float64)

    def measure(self, positions: Array, values: Mapping[str, Array], q_rad: Array, rig: Rig,
                port: NDArray[np.intp] | None = None, point: NDArray[np.intp] | None = None
                ) -> Measurements:
        """The tracker readings the model gives."""
        return Measurements(q_rad, position_m=self._in_tracker(positions, values, rig))

    def jacobian(self, positions: Array, values: Mapping[str, Array], data: Measurements,
                 rig: Rig) -> KindJacobian:
        """∂r/∂p = R_c R_0 at every pose; ∂r/∂t_c = I; ∂r/∂(rx, ry, rz) = ∂R_c/∂a (R_0 p + t_0).
        """
        m = len(data)
        nominal = rig.base_in_tracker
        residuals = self.residuals(positions, values, data, rig)
        turn = nominal[:3, :3]
        by_group: dict[str, Array] = {}
        if "base" in values:
            angles = values["base"][3:]
            turn = rotation(angles) @ turn
            seen = positions @ nominal[:3, :3].T + nominal[:3, 3]
            columns = np.zeros((m, 3, 6))
            columns[:, :, :3] = np.eye(3)
            columns[:, :, 3:] = np.einsum("kij,mj->mik", rotation_derivatives(angles), seen)
            by_group["base"] = columns.reshape(3 * m, 6)
        return KindJacobian(residuals, np.broadcast_to(turn, (m, 3, 3)).copy(), by_group)
