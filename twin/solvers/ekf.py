"""M1 — extended Kalman filter over the training poses (see :mod:`twin.solvers.kalman`).

Random-walk state model, prior 1σ = half the search bound, R = max(σ², f at the pass start), one
iteration = one pass over the training poses in a fixed order shuffled from the seed; each pass
filters from the prior with the model linearised at the previous pass's estimate (iterated EKF).
Stops when f changes by less than ``budget.ftol_m2`` between passes, or after
``budget.max_iterations`` passes.
"""

from __future__ import annotations

import numpy as np

from twin.problem import Budget, Problem
from twin.solvers.base import Solver, SolverResult, Tracker
from twin.solvers.kalman import ekf


def _solve(problem: Problem, budget: Budget, rng: np.random.Generator) -> SolverResult:
    tracker = Tracker(problem, "ekf")
    x, converged = ekf(tracker, problem.x0, budget.max_iterations, rng, budget.ftol_m2)
    return tracker.finish(x, converged)


SOLVER = Solver(name="ekf", alias="m1", title="Extended Kalman filter", solve=_solve)
