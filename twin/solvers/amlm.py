"""M7 — Adaptive-momentum Levenberg–Marquardt (AMLM, paper eqs. 9–13).

Each iteration takes the damped LM step Δx_k (eq. 9, Nielsen's μ rule as in M2) and mixes it with
the previous applied step (eq. 10): ``Δx'_k = γ_k Δx'_{k−1} + (1 − γ_k) Δx_k`` with
``γ_k = γ_max exp(−α |ρ_k − 1|)`` (eq. 11), γ_max = 0.95, α = 0.6, and ρ_k the *relative decrease*
of f achieved by the previous accepted step, ``(f(x_{k−1}) − f(x_k)) / f(x_{k−1})`` (eq. 12 as
printed — not LM's gain ratio). γ_0 = 0.

Our reading where the paper is silent: a step is accepted only if f decreases; on rejection μ is
raised (Nielsen), the momentum is dropped (γ = 0 until the next accepted step) and the step is
retried. The momentum mixes the LM step on the box (as M2 takes it) and the applied step is the
mixture projected onto the box. Every tried step counts as an iteration, as in M2, and the same
tests stop it (:mod:`twin.stopping`).
"""

from __future__ import annotations

import math

import numpy as np

from twin.arrays import Array
from twin.problem import Problem
from twin.solvers.base import Outcome, Solver, SolverResult, Tracker
from twin.solvers.lm import levenberg_marquardt
from twin.stopping import Budget

GAMMA_MAX = 0.95
"""Largest momentum coefficient γ_max (paper)."""
MOMENTUM_DECAY = 0.6
"""Decay sensitivity α of γ to |ρ − 1| (paper)."""


class AdaptiveMomentum:
    """The AMLM step rule (eqs. 10–12) for :func:`~twin.solvers.lm.levenberg_marquardt`."""

    def __init__(self) -> None:
        self.previous: Array | None = None
        """Previous applied step Δx'_{k−1}, shape (p,); None when momentum is off (γ = 0)."""
        self.rho = 0.0
        """Relative decrease of f achieved by the previous accepted step."""

    @property
    def gamma(self) -> float:
        """Current momentum coefficient γ_k."""
        if self.previous is None:
            return 0.0
        return GAMMA_MAX * math.exp(-MOMENTUM_DECAY * abs(self.rho - 1.0))

    def propose(self, tracker: Tracker, x: Array, step: Array) -> Array:
        """Δx'_k = γ_k Δx'_{k−1} + (1 − γ_k) Δx_k."""
        if self.previous is None:
            return step
        gamma = self.gamma
        return gamma * self.previous + (1.0 - gamma) * step

    def accepted(self, step: Array, f_old_m2: float, f_new_m2: float) -> None:
        """Remember the applied step and its relative decrease ρ."""
        self.previous = step
        self.rho = (f_old_m2 - f_new_m2) / f_old_m2

    def rejected(self) -> bool:
        """Drop the momentum; True if there was any (so the pure LM step is worth a retry)."""
        had_momentum = self.previous is not None
        self.previous = None
        return had_momentum


def amlm(tracker: Tracker, x0: Array, budget: Budget, rng: np.random.Generator | None = None
         ) -> Outcome:
    """Run AMLM from ``x0`` (p,) until a test of ``budget`` stops it; see the module docstring.

    AMLM draws nothing at random; ``rng`` is accepted so that it can be a cascade's stage.
    """
    return levenberg_marquardt(tracker, x0, budget, rule=AdaptiveMomentum())


def _solve(problem: Problem, budget: Budget, rng: np.random.Generator) -> SolverResult:
    tracker = Tracker(problem, "amlm")
    return tracker.finish(amlm(tracker, problem.x0, budget))


SOLVER = Solver(name="amlm", title="Adaptive-momentum Levenberg–Marquardt",
                solve=_solve)
