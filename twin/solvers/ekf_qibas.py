"""M5 — EKF cascaded with quadratic-interpolated beetle antennae search (after Li et al., ref. 11).

Table 4 of the paper, which defines M5, is not public; method-notes §4 reconstructs it as an EKF
stage (:func:`twin.solvers.kalman.ekf`) followed by QIBAS. Our reconstruction of QIBAS, in
coordinates scaled by r = 1 mm / 1° (the BIPSO radius) so that one random direction mixes lengths
and angles sensibly:

- a random unit direction b; the beetle's antennae at x ± d·b are evaluated (one batched call);
- two moves are proposed: the beetle-antennae step ``x − δ·b·sign(f_left − f_right)`` (towards the
  better antenna) and the vertex of the parabola through (−d, f_right), (0, f), (+d, f_left)
  along b when it curves upwards, its distance capped at 2δ (one batched call);
- the best of x, the antennae and the moves becomes x (elitist);
- the antenna length decays, d ← 0.95 d, with δ = 2d; d₀ = 0.5 (0.5 mm / 0.5°).

Two stages, see :mod:`twin.solvers.cascade`; under ``converge`` QIBAS stops when its best f
stalls (:mod:`twin.stopping`).
"""

from __future__ import annotations

import numpy as np

from twin.problem import Problem
from twin.solvers.base import Outcome, Solver, SolverResult, Tracker
from twin.solvers.cascade import Array, run_cascade
from twin.solvers.kalman import ekf
from twin.solvers.swarm import initial_radius
from twin.stopping import Budget, StopReason, stalled

ANTENNA_START = 0.5
"""Initial antenna length d₀ in units of r (1 mm / 1°)."""
STEP_RATIO = 2.0
"""Step δ = STEP_RATIO · d."""
DECAY = 0.95
"""Per-iteration decay of d and δ."""


def qibas(tracker: Tracker, x0: Array, budget: Budget, rng: np.random.Generator) -> Outcome:
    """Quadratic-interpolated beetle antennae search from ``x0`` (p,) until ``budget`` stops
    it; returns the best x (p,) seen."""
    problem = tracker.problem
    scale = initial_radius(problem)
    x = np.clip(x0, problem.lower, problem.upper)
    f = float(tracker.cost(x))
    if not tracker.started:
        tracker.record(x, f)
    d = ANTENNA_START
    best_f = [f]
    reason = StopReason.MAX_ITERATIONS
    for _ in range(budget.max_iterations):
        b = rng.standard_normal(x.size)
        b *= scale / np.linalg.norm(b)
        step = STEP_RATIO * d
        antennae = np.clip(np.stack([x + d * b, x - d * b]), problem.lower, problem.upper)
        f_left, f_right = tracker.cost(antennae)
        moves = [x - step * b * np.sign(f_left - f_right)]
        curvature = f_left - 2.0 * f + f_right
        if curvature > 0:
            vertex = d * (f_right - f_left) / (2.0 * curvature)
            moves.append(x + np.clip(vertex, -step, step) * b)
        moves_x = np.clip(np.stack(moves), problem.lower, problem.upper)
        candidates = np.concatenate([x[None], antennae, moves_x])
        costs = np.concatenate([[f, f_left, f_right], tracker.cost(moves_x)])
        best = int(np.argmin(costs))
        x, f = candidates[best], float(costs[best])
        tracker.record(x, f)
        best_f.append(f)
        d *= DECAY
        if stalled(best_f, budget):
            reason = StopReason.STALLED
            break
    return Outcome(x, reason, moved=f < best_f[0])


def _solve(problem: Problem, budget: Budget, rng: np.random.Generator) -> SolverResult:
    return run_cascade(problem, budget, rng, "ekf-qibas", ("ekf", ekf), ("qibas", qibas))


SOLVER = Solver(name="ekf-qibas", title="EKF cascaded with QIBAS", solve=_solve)
