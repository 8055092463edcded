"""Cable lengths: the drawstring encoder reads the distance from its port to the measured point.

For a row whose cable runs from port P_j, ``r = ‖p − (P_j + δP_j)‖ + c − L`` (paper eq. 1 with
the optional port correction δP of group ``port`` and length offset c of group ``offset``).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import Array, lengths
from twin.dataset import Measurements
from twin.geometry.kinematics import Structure, distances, point_position
from twin.kinds.base import KindJacobian, no_symmetries
from twin.rig import Rig


def cable_length(structure: Structure, dh: ArrayLike, q_rad: ArrayLike, port_m: ArrayLike,
                 point_m: ArrayLike | None = None) -> Array:
    """Straight-line cable length from the port to a point on the flange.

    Args:
        structure: What the table means.
        dh: Parameter tables, shape (..., 4, n), m and rad.
        q_rad: Joint angles, shape (m, n), rad.
        port_m: Port position in the base frame, shape (3,) or (..., m, 3), m.
        point_m: The cable's attachment in the flange frame, shape (3,), m; the flange centre
            if None.

    Returns:
        Lengths, shape (..., m), m.
    """
    positions = point_position(structure, dh, q_rad, point_m)
    return lengths(positions - np.asarray(port_m, dtype=np.float64))


class Length:
    """Cable lengths (:mod:`twin.kinds.length`)."""

    name = "length"
    symmetries = staticmethod(no_symmetries)
    rows_per_pose = 1
    groups: tuple[str, ...] = ("port", "offset")

    @staticmethod
    def _ports(values: Mapping[str, Array], data: Measurements, rig: Rig) -> Array:
        """The port of every row, shape (..., m, 3), m."""
        ports = rig.ports_m
        if "port" in values:
            correction = values["port"]
            estimated = rig.estimated_port_index
            full = np.zeros((*correction.shape[:-1], len(rig.ports_m), 3))
            full[..., estimated, :] = correction.reshape(*correction.shape[:-1], len(estimated),
                                                         3)
            ports = ports + full
        return np.asarray(ports[..., data.port_index, :], dtype=np.float64)

    def residuals(self, positions: Array, values: Mapping[str, Array], data: Measurements,
                  rig: Rig) -> Array:
        """r = ‖p − port‖ + offset − L, shape (..., m), m."""
        length = distances(positions, self._ports(values, data, rig))
        if "offset" in values:
            length = length + values["offset"][..., :1]
        assert data.length_m is not None
        return np.asarray(length - data.length_m, dtype=np.float64)

    def measure(self, positions: Array, values: Mapping[str, Array], q_rad: Array, rig: Rig,
                port: NDArray[np.intp] | None = None, point: NDArray[np.intp] | None = None
                ) -> Measurements:
        """The cable lengths the model gives; row i from port ``port[i]`` (port 0 if None)."""
        zeros = Measurements(q_rad, length_m=np.zeros(len(q_rad)), port=port)
        return Measurements(q_rad, length_m=self.residuals(positions, values, zeros, rig),
                            port=port)

    def jacobian(self, positions: Array, values: Mapping[str, Array], data: Measurements,
                 rig: Rig) -> KindJacobian:
        """∂r/∂p = u, the unit vector from the port to the point; ∂r/∂δP_j = −u on the rows
        of estimated port j; ∂r/∂c = 1."""
        difference = positions - self._ports(values, data, rig)
        distance = lengths(difference)
        u = difference / distance[:, None]
        by_group: dict[str, Array] = {}
        if "port" in values:
            columns = np.zeros((len(data), len(rig.ports_m), 3))
            columns[np.arange(len(data)), data.port_index] = -u
            by_group["port"] = columns[:, rig.estimated_port_index].reshape(len(data), -1)
        if "offset" in values:
            distance = distance + values["offset"][0]
            by_group["offset"] = np.ones((len(data), 1))
        assert data.length_m is not None
        return KindJacobian(distance - data.length_m, u[:, None, :], by_group)
