"""Two-stage cascades (M4, M5, M6, M9): a first method, then a second one started from its result.

Under the paper's protocol each stage runs ``budget.stage_iterations`` iterations (30 + 30) and,
as the paper says ("the former iteration runs 30 times, followed by the latter iteration running
30 times"), the f-change rule is not applied inside a cascade; a stage still ends early when it
cannot move (an LM stage whose every unknown is held, say). Under ``converge`` each stage runs
until its own tests stop it (:mod:`twin.stopping`), within ``stage_iterations``.

The result names both stages' stop reasons. It counts as converged when the point it returns is
one where a convergence test fired: the second stage's, or the first stage's when the second
(a search that keeps the best point it has seen) found nothing better. The history runs on
across the stages.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from twin.arrays import Array
from twin.problem import Problem
from twin.solvers.base import Outcome, SolverResult, StageResult, Tracker
from twin.stopping import Budget

StageFunction = Callable[[Tracker, Array, Budget, np.random.Generator], Outcome]
"""``stage(tracker, x_start (p,), budget, rng) -> Outcome``."""


def run_cascade(
    problem: Problem,
    budget: Budget,
    rng: np.random.Generator,
    method: str,
    first: tuple[str, StageFunction],
    second: tuple[str, StageFunction],
) -> SolverResult:
    """Run the ``first`` (name, stage) from ``problem.x0``, then ``second`` from its result."""
    tracker = Tracker(problem, method)
    stage_budget = budget.stage()
    stages = []
    first_outcome = first[1](tracker, problem.x0, stage_budget, rng)
    stages.append(StageResult(first[0], tracker.iterations, first_outcome.reason))
    done = tracker.iterations
    outcome = second[1](tracker, first_outcome.x, stage_budget, rng)
    stages.append(StageResult(second[0], tracker.iterations - done, outcome.reason))
    converged = outcome.reason.converged or (not outcome.moved and first_outcome.reason.converged)
    return tracker.finish_stages(outcome, stages, converged)
