"""A calibration problem as the solvers see it: model, data split, bounds and start.

How long a method runs is its :class:`~twin.stopping.Budget`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from twin.arrays import Array
from twin.dataset import Measurements
from twin.loss import LEAST_SQUARES, Loss
from twin.model import Model
from twin.stopping import scale
from twin.units import mm_to_m

DEFAULT_SIGMA_M = float(mm_to_m(0.01))
"""Default expected length noise (1σ): a 0.01 mm class drawstring encoder."""


@dataclass(frozen=True)
class Problem:
    """What a solver gets: minimise f(x) = mean r(x)² over the training poses inside the box
    (with a robust loss, the mean of each row's cost, :mod:`twin.loss`).

    Attributes:
        model: Maps unknowns x (p,) to residuals.
        train: Poses the objective is computed on.
        validation: Held-out poses, for the history only; solvers never fit to them.
        sigma_m: Expected length noise (1σ), m: the measurement noise of the filters.
        x0: Start (and centre of the initial swarms), shape (p,); empty means zeros (nominal).
        loss: How much each residual row counts; least squares by default.
    """

    model: Model
    train: Measurements
    validation: Measurements
    sigma_m: float = DEFAULT_SIGMA_M
    x0: Array = field(default_factory=lambda: np.zeros(0))
    loss: Loss = LEAST_SQUARES

    def __post_init__(self) -> None:
        x0 = np.array(self.x0, dtype=np.float64)
        if x0.size == 0:
            x0 = np.zeros(self.model.n_params)
        if x0.shape != (self.model.n_params,):
            raise ValueError(f"x0: shape {x0.shape}, expected ({self.model.n_params},)")
        if not self.sigma_m > 0:
            raise ValueError("sigma_m must be > 0")
        x0.setflags(write=False)
        object.__setattr__(self, "x0", x0)

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
        """Scale of each unknown for the step tests: half its search range, shape (p,)."""
        return scale(self.lower, self.upper)
