"""Accuracy metrics of a residual set (paper eq. 32), all in the residuals' unit.

The paper's "STD" is, by its formula, the mean absolute error; here it is ``mae``, and ``std``
is the true standard deviation of the residuals.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike


class Metrics(NamedTuple):
    """Summary of residuals r (same unit as r)."""

    rmse: float
    """sqrt(mean r²)."""
    mae: float
    """mean |r| — what the paper labels "STD"."""
    std: float
    """Standard deviation of r (population, ddof = 0)."""
    max: float
    """max |r|."""


NO_ROWS = Metrics(float("nan"), float("nan"), float("nan"), float("nan"))
"""The metrics of no residuals (a split that leaves no validation pose): not a number."""


def metrics(residuals: ArrayLike) -> Metrics:
    """Metrics of a residual vector, shape (m,); :data:`NO_ROWS` for an empty one."""
    r = np.asarray(residuals, dtype=np.float64)
    if not r.size:
        return NO_ROWS
    return Metrics(
        rmse=float(np.sqrt(np.mean(r**2))),
        mae=float(np.mean(np.abs(r))),
        std=float(np.std(r)),
        max=float(np.max(np.abs(r))),
    )
