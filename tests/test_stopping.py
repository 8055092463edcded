"""Stopping protocols and the tests behind each stop reason."""

from __future__ import annotations

import numpy as np
import pytest

from twin.errors import UnknownChoiceError
from twin.stopping import (
    PAPER_FTOL_M2,
    Budget,
    StopReason,
    at_bounds,
    held_at_bounds,
    optimality,
    small_step,
    stalled,
)


def test_float_equality_of_a_step_and_its_projection_is_no_clipping_test() -> None:
    """The bug this module replaces: a step well inside the box, compared with its projection
    ``clip(x + step) − x``, differs by round-off in most unknowns although none is clipped. The
    bound tests say, correctly, that nothing leaves the box and nothing is held."""
    rng = np.random.default_rng(3)
    lower, upper = np.full(24, -5e-3), np.full(24, 5e-3)
    x = rng.uniform(-4e-3, 4e-3, 24)
    step = rng.uniform(-1e-6, 1e-6, 24)
    projected = np.clip(x + step, lower, upper) - x
    looks_clipped = int(np.sum(projected != step))
    assert looks_clipped >= 5  # what the old test counted as clipped
    assert np.all((x + step >= lower) & (x + step <= upper))
    assert not np.any(held_at_bounds(x, rng.normal(size=24), lower, upper))
    assert not np.any(at_bounds(x + step, lower, upper))


def test_held_at_bounds_needs_the_bound_and_an_outward_push() -> None:
    """An unknown is held only on its bound (within tolerance) with −gradient pointing out."""
    lower, upper = np.array([-1.0, -1.0, -1.0, -1.0]), np.array([1.0, 1.0, 1.0, 1.0])
    x = np.array([-1.0, -1.0 + 1e-12, 1.0, 0.5])
    gradient = np.array([1.0, 1.0, 1.0, 1.0])  # descent direction −g points to lower bounds
    np.testing.assert_array_equal(held_at_bounds(x, gradient, lower, upper),
                                  [True, True, False, False])
    np.testing.assert_array_equal(held_at_bounds(x, -gradient, lower, upper),
                                  [False, False, True, False])


def test_optimality_is_the_largest_cosine_over_free_visible_columns() -> None:
    """MINPACK's measure: |J_iᵀr| / (‖J_i‖ ‖r‖); held and negligible columns do not count."""
    J = np.array([[1.0, 0.0, 1e-20], [0.0, 2.0, 0.0], [0.0, 0.0, 0.0]])

    def measure(r: np.ndarray, held: np.ndarray) -> float:
        return optimality(J.T @ r, np.diag(J.T @ J), float(r @ r), held)

    r = np.array([0.0, 1.0, 1.0])
    assert measure(r, np.zeros(3, bool)) == pytest.approx(1 / np.sqrt(2))
    assert measure(r, np.array([False, True, False])) == pytest.approx(0.0)
    r_orthogonal = np.array([0.0, 0.0, 1.0])
    assert measure(r_orthogonal, np.zeros(3, bool)) == pytest.approx(0.0)


def test_small_step_and_stall() -> None:
    """The step test scales by the unknowns' scale; the stall test needs a whole window."""
    unit = np.array([1e-3, 1e-1])
    x = np.array([1e-3, 1e-1])
    assert small_step(np.array([1e-12, 1e-10]), x, unit, 1e-8)
    assert not small_step(np.array([1e-9, 0.0]), x, unit, 1e-8)
    budget = Budget(stall_iterations=3, ftol=1e-3)
    assert not stalled([1.0, 1.0, 1.0], budget)
    assert stalled([1.0, 1.0, 0.9999, 0.9999], budget)
    assert not stalled([1.0, 0.9, 0.9, 0.9], budget)
    assert not stalled([1.0] * 10, Budget.paper())


def test_protocols() -> None:
    """The paper's protocol is the paper's numbers; converge has every test on; names check."""
    paper = Budget.paper()
    assert (paper.max_iterations, paper.stage_iterations) == (60, 30)
    assert paper.ftol_m2 == pytest.approx(1e-9) == PAPER_FTOL_M2
    assert paper.ftol == paper.xtol == paper.gtol == 0 and paper.stall_iterations == 0
    assert paper.stage().max_iterations == 30 and paper.stage().ftol_m2 == 0
    converge = Budget.named("converge", max_iterations=7)
    assert converge.max_iterations == converge.stage_iterations == 7 and converge.gtol > 0
    with pytest.raises(UnknownChoiceError, match="converge, paper"):
        Budget.named("fast")
    assert [r for r in StopReason if r.converged] == [StopReason.FTOL, StopReason.XTOL,
                                                       StopReason.GTOL]
    for reason in StopReason:
        assert reason.describe(converge)
