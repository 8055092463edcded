"""M1 — extended Kalman filter over the training poses (see :mod:`twin.solvers.kalman`).

Random-walk state model, prior 1σ = half the search bound, R = max(σ², f at the pass start), one
iteration = one pass over the training poses in a fixed order shuffled from the seed; each pass
filters from the prior with the model linearised at the previous pass's estimate (iterated EKF).
Stops as :func:`twin.solvers.kalman.run_filter` says, within ``budget.max_iterations`` passes.
"""

from __future__ import annotations

import numpy as np

from twin.problem import Problem
from twin.solvers.base import Solver, SolverResult, Tracker
from twin.solvers.kalman import ekf
from twin.stopping import Budget


def _solve(problem: Problem, budget: Budget, rng: np.random.Generator) -> SolverResult:
    tracker = Tracker(problem, "ekf")
    return tracker.finish(ekf(tracker, problem.x0, budget, rng))


SOLVER = Solver(name="ekf", title="Extended Kalman filter", solve=_solve)
