"""M3 — global-best particle swarm optimisation (paper eq. 18).

N = 100 particles, ω decreasing linearly 0.9 → 0.4 over the budget, c1 = c2 = 1.49618, velocity
clamped to 20 % of the search range, positions clipped to the bounds (±5 mm / ±8°).

Our reading: M8 is "the improvement of M3", so M3 starts from the same swarm as M8 (eq. 14 with
r = 1 mm / 1° around the nominal x0, slot 0 = x0) and differs from it only by the B-spline step.
The whole swarm is evaluated in one batched call per iteration. Under the paper's protocol it
runs its whole 60 iterations; under ``converge`` until it stalls (see :mod:`twin.solvers.swarm`).
"""

from __future__ import annotations

import numpy as np

from twin.problem import Problem
from twin.solvers.base import Solver, SolverResult, Tracker
from twin.solvers.swarm import particle_swarm
from twin.stopping import Budget


def _solve(problem: Problem, budget: Budget, rng: np.random.Generator) -> SolverResult:
    tracker = Tracker(problem, "pso")
    return tracker.finish(particle_swarm(tracker, problem.x0, budget, rng, n_interpolated=0))


SOLVER = Solver(name="pso", title="Particle swarm optimisation", solve=_solve)
