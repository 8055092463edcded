"""Robust losses: how much a residual row counts, so that a few gross errors cannot steer a fit.

With a scale c and z = (r / c)², the cost of a row is ``c² ρ(z)`` (scipy's definitions):

- ``linear``: ρ = z (least squares; the default);
- ``huber``: ρ = z for z ≤ 1, 2√z − 1 beyond — quadratic near zero, linear in |r| far out;
- ``soft_l1``: ρ = 2(√(1 + z) − 1) — a smooth Huber;
- ``cauchy``: ρ = ln(1 + z) — a far residual's cost grows only logarithmically.

Every method minimises the mean cost over the training rows (:class:`twin.problem.Problem`
carries the loss). The least-squares methods (LM, AMLM, the LM stages of the cascades) see it as
reweighted rows (iteratively reweighted least squares with the weights recomputed at every
iterate): row i becomes ``s_i = r_i √(ρ(z_i)/z_i)``, so that Σ s² is exactly the robust cost,
and its Jacobian row is scaled by ``ds/dr = ρ'(z) / √(ρ(z)/z)`` — the model's analytic Jacobian
times a factor per row. At a stationary point ``Jᵀ diag(ρ'(z)) r = 0``, the IRLS normal
equations. The Kalman filters read the loss as their measurement model (:mod:`twin.solvers.kalman`);
the swarms compare candidates by the robust cost itself.

A row is **rejected** when its residual at the solution lies beyond :data:`REJECT_SCALES` scales:
there every loss has flattened (Huber's weight ρ' is below 1/3, Cauchy's below 1/10), so the
row barely moves the fit. Rejected rows are listed, never dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import Array
from twin.choices import LOSSES
from twin.errors import UnknownChoiceError

REJECT_SCALES = 3.0
"""A row whose residual exceeds this many loss scales counts as rejected."""
_SERIES_Z = 1e-8
"""Below this z, ln(1 + z)/z is evaluated by its series (1 − z/2), free of 0/0."""


def check_loss(name: str) -> str:
    """``name`` if it is a loss.

    Raises:
        UnknownChoiceError: listing the losses.
    """
    if name not in LOSSES:
        raise UnknownChoiceError("loss", name, LOSSES)
    return name


@dataclass(frozen=True)
class Loss:
    """A loss and its scale.

    Attributes:
        name: One of :data:`LOSSES`.
        scale_m: The scale c, m (> 0): residuals well below it count as in least squares.
    """

    name: str = "linear"
    scale_m: float = 1.0

    def __post_init__(self) -> None:
        check_loss(self.name)
        if not (np.isfinite(self.scale_m) and self.scale_m > 0):
            raise ValueError(f"scale_m: {self.scale_m}, expected a finite value > 0")

    @property
    def robust(self) -> bool:
        """Whether this is not least squares."""
        return self.name != "linear"

    def _z(self, residuals_m: ArrayLike) -> Array:
        return np.asarray((np.asarray(residuals_m, dtype=np.float64) / self.scale_m) ** 2)

    def rho(self, z: ArrayLike) -> Array:
        """ρ(z), elementwise."""
        z = np.asarray(z, dtype=np.float64)
        if self.name == "huber":
            return np.where(z <= 1.0, z, 2.0 * np.sqrt(z) - 1.0)
        if self.name == "soft_l1":
            return 2.0 * z / (np.sqrt(1.0 + z) + 1.0)  # 2(√(1 + z) − 1) without cancellation
        if self.name == "cauchy":
            return np.log1p(z)
        return z

    def weights(self, residuals_m: ArrayLike) -> Array:
        """ρ'(z) of each row: the IRLS weight, 1 for least squares; same shape as the rows."""
        z = self._z(residuals_m)
        if self.name == "huber":
            return 1.0 / np.sqrt(np.maximum(z, 1.0))
        if self.name == "soft_l1":
            return 1.0 / np.sqrt(1.0 + z)
        if self.name == "cauchy":
            return 1.0 / (1.0 + z)
        return np.ones_like(z)

    def _ratio(self, z: Array) -> Array:
        """ρ(z) / z, continuous at z = 0 (where it is 1)."""
        if self.name == "huber":
            big = np.maximum(z, 1.0)
            return np.where(z <= 1.0, 1.0, (2.0 * np.sqrt(big) - 1.0) / big)
        if self.name == "soft_l1":
            return 2.0 / (np.sqrt(1.0 + z) + 1.0)
        if self.name == "cauchy":
            safe = np.maximum(z, _SERIES_Z)
            return np.where(z < _SERIES_Z, 1.0 - z / 2.0, np.log1p(safe) / safe)
        return np.ones_like(z)

    def cost(self, residuals_m: ArrayLike) -> Array:
        """Each row's cost c² ρ(z), m² (r² for least squares); same shape as the rows."""
        r = np.asarray(residuals_m, dtype=np.float64)
        if not self.robust:
            return r**2
        return self.scale_m**2 * self.rho(self._z(r))

    def rows(self, residuals_m: ArrayLike, jacobian: ArrayLike) -> tuple[Array, Array]:
        """The reweighted rows least squares iterates on: s (M,) with Σ s² = Σ cost, and
        ∂s/∂x (M, p), from the residuals r (M,) and their Jacobian (M, p)."""
        r = np.asarray(residuals_m, dtype=np.float64)
        J = np.asarray(jacobian, dtype=np.float64)
        if not self.robust:
            return r, J
        z = self._z(r)
        root = np.sqrt(self._ratio(z))
        slope = self.weights(r) / root
        return r * root, J * slope[:, None]

    def rejected(self, residuals_m: ArrayLike) -> NDArray[np.bool_]:
        """Rows beyond :data:`REJECT_SCALES` scales (none for least squares)."""
        r = np.asarray(residuals_m, dtype=np.float64)
        if not self.robust:
            return np.zeros(r.shape, dtype=bool)
        return np.asarray(np.abs(r) > REJECT_SCALES * self.scale_m)


LEAST_SQUARES = Loss()
"""Plain least squares."""
