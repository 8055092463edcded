"""Two-stage cascades (M4, M5, M6, M9): a first method, then a second one started from its result.

Each stage runs ``budget.stage_iterations`` iterations (paper: 30 + 30). As the paper says ("the
former iteration runs 30 times, followed by the latter iteration running 30 times"), the f-change
stopping rule is not applied inside a cascade (stages use :data:`STAGE_FTOL_M2` = 0); a stage still
ends early if it cannot move (LM with a zero step). The history runs on across the stages.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from twin.problem import Budget, Problem
from twin.solvers.base import SolverResult, Tracker

Array = NDArray[np.float64]

Stage = Callable[[Tracker, Array, int, np.random.Generator], Array]
"""``stage(tracker, x_start (p,), iterations, rng) -> x (p,)``, run for its whole budget."""

STAGE_FTOL_M2 = 0.0
"""f-change threshold inside a cascade: 0, the stages run their whole budget."""


def run_cascade(
    problem: Problem,
    budget: Budget,
    rng: np.random.Generator,
    method: str,
    first: Stage,
    second: Stage,
) -> SolverResult:
    """Run ``first`` from ``problem.x0``, then ``second`` from its result, in one tracker."""
    tracker = Tracker(problem, method)
    x_first = first(tracker, problem.x0, budget.stage_iterations, rng)
    x = second(tracker, x_first, budget.stage_iterations, rng)
    return tracker.finish(x, converged=False)
