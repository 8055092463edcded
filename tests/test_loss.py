"""Robust losses: the reweighted rows carry exactly the robust cost and its analytic Jacobian."""

from __future__ import annotations

import numpy as np
import pytest

from twin.choices import LOSSES
from twin.errors import UnknownChoiceError
from twin.loss import REJECT_SCALES, Loss


@pytest.mark.parametrize("name", LOSSES)
def test_rows_carry_the_cost_and_its_derivative(name: str) -> None:
    """Σ s² = Σ c² ρ(z), and ds/dr (the Jacobian factor) equals differences of s(r), from
    residuals far below the scale to far beyond it."""
    loss = Loss(name, 1e-4)
    r = np.array([-3e-3, -2e-4, -1e-5, 0.0, 1e-12, 5e-5, 1.5e-4, 2e-3])
    s, slope = loss.rows(r, np.eye(r.size))
    np.testing.assert_allclose(s**2, loss.cost(r), rtol=1e-12, atol=1e-30)
    eps = 1e-10
    numeric = (loss.rows(r + eps, np.eye(r.size))[0] - loss.rows(r - eps, np.eye(r.size))[0]) \
        / (2 * eps)
    np.testing.assert_allclose(np.diag(slope), numeric, rtol=1e-5, atol=1e-9)
    # The gradient of the cost is that of IRLS: d(c²ρ)/dr = 2 ρ'(z) r.
    np.testing.assert_allclose(2 * s * np.diag(slope), 2 * loss.weights(r) * r, rtol=1e-10,
                               atol=1e-20)


def test_small_residuals_count_as_in_least_squares() -> None:
    """Far below the scale every loss is r², and Huber is exactly r² up to the scale."""
    r = np.array([1e-7, -2e-7])
    for name in LOSSES:
        np.testing.assert_allclose(Loss(name, 1e-3).cost(r), r**2, rtol=1e-6)
    np.testing.assert_allclose(Loss("huber", 1e-3).cost([9e-4]), np.array([9e-4]) ** 2,
                               rtol=1e-15)


def test_rejected_rows_lie_beyond_three_scales() -> None:
    """Rejected: |r| > 3 c for a robust loss, never for least squares."""
    r = np.array([0.0, 2.9e-3, -3.1e-3, 1.0])
    assert REJECT_SCALES == 3.0
    np.testing.assert_array_equal(Loss("cauchy", 1e-3).rejected(r), [False, False, True, True])
    assert not Loss("linear").rejected(r).any()


def test_an_unknown_loss_lists_the_losses() -> None:
    """A misspelt loss names the valid ones; a scale must be positive."""
    with pytest.raises(UnknownChoiceError, match="huber, soft_l1, cauchy"):
        Loss("hubber", 1e-3)
    with pytest.raises(ValueError, match="scale_m"):
        Loss("huber", 0.0)
