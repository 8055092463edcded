"""How well a compensation works: the true flange errors over targets, commanded through the
nominal model and through the compensated one (the twin, or a tracker, says where the flange
really went).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from twin.analysis.metrics import Metrics, metrics
from twin.arrays import Array
from twin.compensation.ik import IKResult


class CompensationCheck(NamedTuple):
    """True flange errors over targets, commanded through the nominal or the identified model.

    Attributes:
        nominal_error_m: Distance from the target with the nominal solutions, shape (k,), m.
        compensated_error_m: Distance with the compensated solutions, shape (k,), m.
        n_failed: Targets whose compensated solution was not ok (left out of both arrays).
    """

    nominal_error_m: Array
    compensated_error_m: Array
    n_failed: int

    @property
    def nominal(self) -> Metrics:
        """Metrics of :attr:`nominal_error_m` (mae is the mean distance), m."""
        return metrics(self.nominal_error_m)

    @property
    def compensated(self) -> Metrics:
        """Metrics of :attr:`compensated_error_m`, m."""
        return metrics(self.compensated_error_m)

    @property
    def n_targets(self) -> int:
        """Targets drawn."""
        return len(self.nominal_error_m) + self.n_failed


def check_compensation(
    base_p_target: ArrayLike,
    true_at_nominal_m: ArrayLike,
    true_at_compensated_m: ArrayLike,
    compensated: IKResult,
) -> CompensationCheck:
    """Summarise the true flange errors without and with compensation.

    Args:
        base_p_target: Targets, shape (m, 3), m.
        true_at_nominal_m: True flange at the nominal solutions, shape (m, 3), m.
        true_at_compensated_m: True flange at the compensated solutions, shape (m, 3), m.
        compensated: The compensated IK result; rows that are not ok are left out of both.
    """
    ok = compensated.ok
    target = np.asarray(base_p_target)[ok]
    before = np.linalg.norm(np.asarray(true_at_nominal_m)[ok] - target, axis=-1)
    after = np.linalg.norm(np.asarray(true_at_compensated_m)[ok] - target, axis=-1)
    return CompensationCheck(before, after, int(np.sum(~ok)))
