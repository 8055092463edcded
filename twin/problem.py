"""A calibration problem as the solvers see it: model, data split, bounds, start — and the one
objective every method minimises.

The objective's rows are formed here and nowhere else, so that every method (least squares,
filters, swarms, cascades) minimises the same thing:

1. the training residuals, each row r_i scaled by σ / σ_i — σ the stated noise of a reading,
   σ_i that row's own (:meth:`Problem.row_sigma`: the reading's noise and the joints' noise
   through the row's Jacobian, errors in variables; σ_i = σ, and the rows unchanged, when the
   joints are taken as exact);
2. a robust loss on those rows, if any (:mod:`twin.loss`);
3. then one row ``σ · x_j / σ_p,j`` per unknown with a prior N(0, σ_p,j²) (method-notes §7:
   Tikhonov regularisation towards the nominal, never touched by the loss).

Every row is a reading of noise σ under the stated model, so the filters take each as a
measurement of variance σ², and f = mean of the rows' costs (m²) is the objective.
How long a method runs is its :class:`~twin.stopping.Budget`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from twin.arrays import Array
from twin.choices import DEFAULT_SIGMA_MM
from twin.dataset import Measurements
from twin.loss import LEAST_SQUARES, Loss
from twin.model import Model
from twin.units import mm_to_m

DEFAULT_SIGMA_M = float(mm_to_m(DEFAULT_SIGMA_MM))
"""Default expected length noise (1σ): a 0.01 mm class drawstring encoder."""


@dataclass(frozen=True)
class Problem:
    """What a solver gets: minimise f(x), the mean of the objective's rows' costs (module
    docstring), over the training poses inside the box.

    Attributes:
        model: Maps unknowns x (p,) to residuals.
        train: Poses the objective is computed on.
        validation: Held-out poses, for the history only; solvers never fit to them (may be
            empty: every pose trained on).
        sigma_m: Expected noise (1σ) of a reading, m: the measurement noise of the filters and
            the unit every row of the objective is scaled to.
        x0: Start (and centre of the initial swarms), shape (p,); empty means zeros (nominal).
        loss: How much each residual row counts; least squares by default.
        joint_sigma_rad: The noise 1σ of each recorded joint angle, shape (n,), rad (a
            resolution r gives r/√12); zeros (the default) take the joints as exact.
        linearised_at: Where the rows' joint Jacobians g_i = ∂r_i/∂q are evaluated, shape (p,);
            empty means ``x0``. A calibration evaluates them again at its first answer.
    """

    model: Model
    train: Measurements
    validation: Measurements
    sigma_m: float = DEFAULT_SIGMA_M
    x0: Array = field(default_factory=lambda: np.zeros(0))
    loss: Loss = LEAST_SQUARES
    joint_sigma_rad: Array = field(default_factory=lambda: np.zeros(0))
    linearised_at: Array = field(default_factory=lambda: np.zeros(0))
    _train_weight: Array = field(init=False, repr=False, compare=False)
    _prior: Array = field(init=False, repr=False, compare=False)
    _in_variables: bool = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        p, n = self.model.n_params, self.model.robot.n_joints
        x0 = np.array(self.x0, dtype=np.float64)
        if x0.size == 0:
            x0 = np.zeros(p)
        if x0.shape != (p,):
            raise ValueError(f"x0: shape {x0.shape}, expected ({p},)")
        if not self.sigma_m > 0:
            raise ValueError("sigma_m must be > 0")
        joints = np.array(self.joint_sigma_rad, dtype=np.float64)
        joints = np.zeros(n) if joints.size == 0 else joints
        if joints.shape != (n,) or not np.all(np.isfinite(joints) & (joints >= 0)):
            raise ValueError(f"joint_sigma_rad: expected ({n},) values >= 0")
        at = np.array(self.linearised_at, dtype=np.float64)
        at = x0.copy() if at.size == 0 else at
        if at.shape != (p,):
            raise ValueError(f"linearised_at: shape {at.shape}, expected ({p},)")
        for name, value in (("x0", x0), ("joint_sigma_rad", joints), ("linearised_at", at)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "_in_variables", bool(np.any(joints > 0)))
        object.__setattr__(self, "_train_weight", self.sigma_m / self.row_sigma(self.train))
        object.__setattr__(self, "_prior", np.flatnonzero(self.model.prior_weight() > 0))

    @property
    def lower(self) -> Array:
        """Lower bounds of x, shape (p,)."""
        return self.model.bounds()[0]

    @property
    def upper(self) -> Array:
        """Upper bounds of x, shape (p,)."""
        return self.model.bounds()[1]

    @property
    def scale(self) -> Array:
        """Scale of each unknown for the step tests, shape (p,): its prior's σ, else half its
        search range (:meth:`twin.model.Model.scale`)."""
        return self.model.scale()

    @property
    def in_variables(self) -> bool:
        """Whether the joints' noise enters the rows' variances (errors in variables)."""
        return self._in_variables

    def row_sigma(self, data: Measurements) -> Array:
        """The noise 1σ of each residual row of ``data``, shape (M,), m: the reading's σ and the
        joints' noise through the row's Jacobian, sqrt(σ² + Σ_j (∂r_i/∂q_j σ_q,j)²)
        (method-notes §7), evaluated at :attr:`linearised_at`; σ for every row when the joints
        are exact."""
        if not self.in_variables:
            rows = self.model.residuals(self.x0, data).shape[-1]
            return np.full(rows, self.sigma_m)
        moves = self.model.joint_jacobian(self.linearised_at, data) * self.joint_sigma_rad
        return np.asarray(np.sqrt(self.sigma_m**2 + np.sum(moves**2, axis=1)), dtype=np.float64)

    @property
    def train_weight(self) -> Array:
        """σ / σ_i of each training row, shape (M,): 1 when the joints are exact."""
        return self._train_weight

    @property
    def prior_rows(self) -> int:
        """How many prior rows the objective appends."""
        return int(self._prior.size)

    def data_residuals(self, x: ArrayLike) -> Array:
        """The training rows scaled to the noise σ, r_i σ / σ_i, for unknowns (..., p): shape
        (..., M), m."""
        rows = self.model.residuals(x, self.train)
        # σ / σ_i is exactly 1 on every row when the joints are exact: a swarm's batch of
        # candidates skips multiplying by it.
        return rows * self._train_weight if self.in_variables else rows

    def data_jacobian(self, x: ArrayLike) -> tuple[Array, Array]:
        """:meth:`data_residuals` (M,) and their Jacobian (M, p) at one x (p,)."""
        r, jacobian = self.model.jacobian(x, self.train)
        if not self.in_variables:  # every weight is exactly 1 (as in data_residuals)
            return r, jacobian
        return r * self._train_weight, jacobian * self._train_weight[:, None]

    def _prior_residuals(self, x: ArrayLike) -> Array:
        weight = self.sigma_m * self.model.prior_weight()[self._prior]
        return np.asarray(np.asarray(x, dtype=np.float64)[..., self._prior] * weight,
                          dtype=np.float64)

    def residuals(self, x: ArrayLike) -> Array:
        """The objective's rows before the loss, for unknowns (..., p): the scaled training rows,
        then the prior rows σ x_j / σ_p,j; shape (..., M + P), m."""
        if not self._prior.size:
            return self.data_residuals(x)
        return np.concatenate([self.data_residuals(x), self._prior_residuals(x)], axis=-1)

    def jacobian(self, x: ArrayLike) -> tuple[Array, Array]:
        """:meth:`residuals` (M + P,) and their Jacobian (M + P, p) at one x (p,)."""
        r, jacobian = self.data_jacobian(x)
        if not self._prior.size:
            return r, jacobian
        prior = np.zeros((self._prior.size, self.model.n_params))
        prior[np.arange(self._prior.size), self._prior] = \
            self.sigma_m * self.model.prior_weight()[self._prior]
        return (np.concatenate([r, self._prior_residuals(x)]),
                np.concatenate([jacobian, prior]))

    def cost(self, rows: ArrayLike) -> Array:
        """f: the mean of the rows' costs (the loss on the training rows, squares of the prior
        rows), for rows (..., M + P) of :meth:`residuals`: shape (...,), m²."""
        rows = np.asarray(rows, dtype=np.float64)
        if not self._prior.size:  # the swarms' case, without the prior's empty sums
            return np.asarray(np.sum(self.loss.cost(rows), axis=-1) / rows.shape[-1],
                              dtype=np.float64)
        split = rows.shape[-1] - self._prior.size
        total = np.sum(self.loss.cost(rows[..., :split]), axis=-1) \
            + np.sum(rows[..., split:] ** 2, axis=-1)
        return np.asarray(total / rows.shape[-1], dtype=np.float64)

    def objective(self, x: ArrayLike) -> Array:
        """f at unknowns (..., p), shape (...,), m²: :meth:`cost` of :meth:`residuals`; for
        least squares on rows of equal noise without priors, the model's sum of squares
        where it has one (:meth:`twin.model.Model.sum_squares`: a swarm's candidates, summed
        in the chain's pass), the same to round-off."""
        if not (self.loss.robust or self.in_variables or self._prior.size):
            total = self.model.sum_squares(x, self.train)
            if total is not None:
                return np.asarray(total / self._train_weight.size, dtype=np.float64)
        return self.cost(self.residuals(x))

    def loss_rows(self, rows: ArrayLike, jacobian: ArrayLike) -> tuple[Array, Array]:
        """The rows least squares iterates on (:meth:`twin.loss.Loss.rows` on the training rows,
        the prior rows as they are), from :meth:`jacobian`'s: (M + P,), (M + P, p)."""
        rows = np.asarray(rows, dtype=np.float64)
        jacobian = np.asarray(jacobian, dtype=np.float64)
        if not self._prior.size:
            return self.loss.rows(rows, jacobian)
        split = rows.size - self._prior.size
        r, J = self.loss.rows(rows[:split], jacobian[:split])
        return np.concatenate([r, rows[split:]]), np.concatenate([J, jacobian[split:]])

    def loss_weights(self, rows: ArrayLike) -> Array:
        """The loss's IRLS weight ρ'(z) of each row of :meth:`residuals` (1 for a prior row),
        shape (M + P,)."""
        rows = np.asarray(rows, dtype=np.float64)
        split = rows.size - self._prior.size
        return np.concatenate([self.loss.weights(rows[:split]), np.ones(self._prior.size)])
