"""M6 — EKF cascaded with quantum-behaved PSO (after Cao et al., the paper's ref. 13).

Table 4 of the paper, which defines M6, is not public; method-notes §4 reconstructs it as an EKF
stage (:func:`twin.solvers.kalman.ekf`) followed by QPSO (Sun et al.), without ref. 13's dual
swarm and ANFIS parts. QPSO: N = 100 particles around the EKF result (the BIPSO initial swarm of
:func:`twin.solvers.swarm.initial_swarm`), each moved to
``p_i ± β |mbest − x_i| ln(1/u)`` with the local attractor ``p_i = φ P_i + (1 − φ) G``,
φ, u ~ U(0, 1) per dimension, a fair coin for the sign, mbest the mean personal best and the
contraction–expansion coefficient β decreasing linearly 1.0 → 0.5. The swarm is evaluated in one
batched call per iteration (:func:`twin.solvers.swarm.run_population`). Two stages, see
:mod:`twin.solvers.cascade`; β's schedule spans the stage's iteration limit.
"""

from __future__ import annotations

import numpy as np

from twin.problem import Problem
from twin.solvers.base import Outcome, Solver, SolverResult, Tracker
from twin.solvers.cascade import Array, run_cascade
from twin.solvers.kalman import ekf
from twin.solvers.swarm import N_PARTICLES, Swarm, initial_swarm, run_population
from twin.stopping import Budget

BETA_START, BETA_END = 1.0, 0.5
"""Contraction–expansion coefficient, decreasing linearly over the stage."""


def qpso(tracker: Tracker, center: Array, budget: Budget, rng: np.random.Generator) -> Outcome:
    """Quantum-behaved PSO around ``center`` (p,) until ``budget`` stops it."""
    iterations = budget.max_iterations
    lower, upper = tracker.problem.lower, tracker.problem.upper

    def move(swarm: Swarm, k: int) -> Array:
        beta = BETA_START - (BETA_START - BETA_END) * k / max(iterations - 1, 1)
        phi, u, coin = rng.random((3, *swarm.x.shape))
        attractor = phi * swarm.best_x + (1.0 - phi) * swarm.g_x
        mbest = np.mean(swarm.best_x, axis=0)
        spread = beta * np.abs(mbest - swarm.x) * np.log(1.0 / (1.0 - u))  # 1 − u ∈ (0, 1]
        return np.clip(np.where(coin < 0.5, attractor - spread, attractor + spread), lower, upper)

    x_init = initial_swarm(tracker.problem, np.asarray(center, dtype=np.float64), N_PARTICLES, rng)
    return run_population(tracker, x_init, budget, move)


def _solve(problem: Problem, budget: Budget, rng: np.random.Generator) -> SolverResult:
    return run_cascade(problem, budget, rng, "ekf-qpso", ("ekf", ekf), ("qpso", qpso))


SOLVER = Solver(name="ekf-qpso", title="EKF cascaded with quantum-behaved PSO",
                solve=_solve)
