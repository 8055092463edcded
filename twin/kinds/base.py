"""The one interface of a measurement kind: residuals from the measured point's positions.

The model (:class:`twin.model.Model`) computes where the measured point is at every pose; the
kind turns those positions, the rig and the values of the measurement-stage unknowns it reads
into residuals, and gives their derivatives. Residual rows: ``rows_per_pose`` per pose, pose by
pose, then any rows that belong to no pose (a known distance between two fixed points, say).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, NamedTuple, Protocol

import numpy as np
from numpy.typing import NDArray

from twin.arrays import Array
from twin.dataset import Measurements
from twin.rig import Rig

if TYPE_CHECKING:
    from twin.model import Model



class KindJacobian(NamedTuple):
    """Residuals at one x and their derivatives."""

    residuals: Array
    """r, shape (M,), in the measurement's unit (m)."""
    by_position: Array
    """∂r/∂p of each pose's rows w.r.t. that pose's point, shape (m, rows_per_pose, 3)."""
    by_group: dict[str, Array]
    """∂r/∂x_g of each measurement-stage group the kind reads, shape (M, p_g)."""


def no_symmetries(model: Model, x: Array) -> Array:
    """No direction to project out: shape (p, 0)."""
    return np.zeros((model.n_params, 0))


class Kind(Protocol):
    """A measurement kind."""

    name: str
    """``length``, ``position`` or ``point`` (:data:`twin.kinds.KINDS`)."""
    rows_per_pose: int
    """Residual rows per pose: 1 for a length, 3 for a position."""
    groups: tuple[str, ...]
    """The measurement-stage unknown groups it reads."""

    def residuals(self, positions: Array, values: Mapping[str, Array], data: Measurements,
                  rig: Rig) -> Array:
        """Residuals for positions (..., m, 3) and group values (..., p_g): shape (..., M)."""
        ...

    def jacobian(self, positions: Array, values: Mapping[str, Array], data: Measurements,
                 rig: Rig) -> KindJacobian:
        """Residuals and derivatives at one x: positions (m, 3), values (p_g,)."""
        ...

    def measure(self, positions: Array, values: Mapping[str, Array], q_rad: Array, rig: Rig,
                port: NDArray[np.intp] | None = None, point: NDArray[np.intp] | None = None
                ) -> Measurements:
        """Noise-free readings of this kind at positions (m, 3) and values (p_g,): the data
        the model fits exactly (for identifiability on synthetic poses, and for tests); row i
        from port ``port[i]`` (cable lengths) or at fixed place ``point[i]`` (fixed points)."""
        ...

    def symmetries(self, model: Model, x: Array) -> Array:
        """Directions of x (p, g) along which the kind's cost is exactly flat although its
        linearised rows are not (they move the residuals only by rotating or scaling them):
        the known gauge group that :meth:`twin.model.Model.identifiable_jacobian` projects out.
        Empty (p, 0) for kinds whose gauge freedoms are exact null directions of the Jacobian.
        """
        ...
