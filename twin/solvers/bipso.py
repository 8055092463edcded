"""M8 — B-spline-interpolated particle swarm optimisation (BIPSO, paper eqs. 14–31).

Initial swarm (eq. 14) of N = 100 particles ``x_c + r ⊙ (2·rand − 1)``, r = 1 mm for δa, δd and
1° for δα, δθ (the text's ±1 mm / ±1°; eq. 14's ``ub − lb`` would span the whole box), slot 0 =
x_c. Standalone, x_c is the nominal x0; in M9 it is the AMLM result.

Each iteration: the PSO update of M3 (eq. 18), then the B-spline step. Our reading of eqs. 19–31:

- eq. 23 uses one parameter t_i for all dimensions, so the curve is ONE curve in R^p through the
  N updated particles in index order, with chord-length parameters from full-vector distances
  (eqs. 20–22) normalised to [0, 1]; zero-length chords (duplicate particles) are dropped;
- the curve is the cubic interpolating B-spline (eqs. 24–26), built by
  ``scipy.interpolate.make_interp_spline(t, X, k=3)``, sampled at M = 100 evenly spaced t (eq. 27);
- eqs. 29–31 read literally replace the swarm by the best interpolated points. We pool the N
  updated particles with the M interpolated points, keep the best N (velocities and personal
  bests stay with their slots) and keep G_best elitist — never worse than before.

All N + M candidates are evaluated in one batched call per iteration. It stops like M3.
"""

from __future__ import annotations

import numpy as np

from twin.problem import Problem
from twin.solvers.base import Outcome, Solver, SolverResult, Tracker
from twin.solvers.swarm import N_INTERPOLATED, Array, particle_swarm
from twin.stopping import Budget


def bipso(tracker: Tracker, center: Array, budget: Budget, rng: np.random.Generator) -> Outcome:
    """Run BIPSO around ``center`` (p,) until ``budget`` stops it; G_best and why it stopped."""
    return particle_swarm(tracker, center, budget, rng, n_interpolated=N_INTERPOLATED)


def _solve(problem: Problem, budget: Budget, rng: np.random.Generator) -> SolverResult:
    tracker = Tracker(problem, "bipso")
    return tracker.finish(bipso(tracker, problem.x0, budget, rng))


SOLVER = Solver(name="bipso", title="B-spline-interpolated PSO", solve=_solve)
