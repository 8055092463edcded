"""M4 — UKF cascaded with variable-step-size LM (after Li et al., the paper's ref. 6).

Table 4 of the paper, which defines M4, is not public; method-notes §4 reconstructs it as a UKF
stage (:func:`twin.solvers.kalman.ukf`: 2p sigma points per pose, evaluated in one batched call)
followed by a variable-step-size LM. Our reconstruction of the latter: the damped LM step Δx
(M2's loop and μ rule) is scaled by the step length η from {0.5, 1, 1.5, 2} that gives the
lowest f — all four candidates evaluated in one batched call — so the step length adapts each
iteration beside μ. Two stages, see :mod:`twin.solvers.cascade`.
"""

from __future__ import annotations

import numpy as np

from twin.problem import Problem
from twin.solvers.base import Outcome, Solver, SolverResult, Tracker
from twin.solvers.cascade import Array, run_cascade
from twin.solvers.kalman import ukf
from twin.solvers.lm import levenberg_marquardt
from twin.stopping import Budget

STEP_LENGTHS = np.array([0.5, 1.0, 1.5, 2.0])
"""Candidate multipliers η of the LM step."""


class VariableStepLength:
    """Step rule for :func:`~twin.solvers.lm.levenberg_marquardt`: best η·Δx of the candidates."""

    def propose(self, tracker: Tracker, x: Array, step: Array) -> Array:
        """η·Δx with η minimising f over :data:`STEP_LENGTHS` (one batched evaluation)."""
        problem = tracker.problem
        trials = np.clip(x + STEP_LENGTHS[:, None] * step, problem.lower, problem.upper)
        return trials[int(np.argmin(tracker.cost(trials)))] - x

    def accepted(self, step: Array, f_old_m2: float, f_new_m2: float) -> None:
        """Nothing to remember: η is chosen afresh each iteration."""

    def rejected(self) -> bool:
        """Nothing to drop; the retry comes from the larger μ."""
        return False


def vslm(tracker: Tracker, x0: Array, budget: Budget, rng: np.random.Generator) -> Outcome:
    """Variable-step-size LM from ``x0`` (p,) until ``budget`` stops it; see the module doc."""
    return levenberg_marquardt(tracker, x0, budget, rule=VariableStepLength())


def _solve(problem: Problem, budget: Budget, rng: np.random.Generator) -> SolverResult:
    return run_cascade(problem, budget, rng, "ukf-vslm", ("ukf", ukf), ("vslm", vslm))


SOLVER = Solver(name="ukf-vslm", title="UKF cascaded with variable-step LM",
                solve=_solve)
