"""Population machinery shared by the swarm methods (M3 PSO, M6's QPSO, M8 BIPSO, M9).

- :func:`initial_swarm`: paper eq. 14 read with the text's radius, ``x_c + r ⊙ (2·rand − 1)`` with
  r = 1 mm for lengths and 1° for angles, and the centre itself as slot 0 (so a cascade's second
  stage never starts worse than the first stage ended; see docs/methods.md).
- :func:`pso_velocity`: the global-best PSO update (eq. 18) with ω from 0.9 to 0.4, c1 = c2 =
  1.49618 and the velocity clamped to 20 % of the search range.
- :func:`interpolating_curve` / :func:`interpolated_points`: the B-spline step of BIPSO
  (eqs. 19–27): one cubic curve in R^p through the particles in index order, chord-length
  parameters from full-vector distances normalised to [0, 1] (eqs. 20–22), interpolated with
  :func:`scipy.interpolate.make_interp_spline` and sampled at M evenly spaced parameters (with
  the extra ``fast``, in a study's workers, the same curve drawn by a compiled kernel, and
  each iteration's moves and selection in one compiled call each: :mod:`twin.solvers.compiled`).
- :func:`run_population`: the loop. Each iteration a method proposes K ≥ N candidates, all are
  evaluated in ONE batched call, the best N are kept (:func:`best_in_slots`: velocities and
  personal bests stay with their slots), personal and global bests are updated elitistically, and
  G_best's f is recorded.

Stopping: under the paper's protocol a swarm runs its whole iteration budget. The f-change rule
of method-notes §3 is not applied to swarms: G_best routinely stalls for several iterations while
the swarm still moves, so "f changed by less than 0.001 mm²" would stop a swarm at random (in
our runs BIPSO stopped at iteration 3, 1 mm from the optimum). The paper's times — M3 and M8 the
slowest — fit swarms that ran their whole budget. Under ``converge`` a swarm stops when G_best
has not improved by ``ftol`` (relative) in ``stall_iterations`` iterations (*stalled*: no proof
of an optimum, and reported as such). The inertia and contraction schedules span the iteration
limit.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from typing import TYPE_CHECKING

import numpy as np

from twin.arrays import Array
from twin.geometry.kinematics import takes_compiled
from twin.problem import Problem
from twin.solvers.base import Outcome, Tracker
from twin.stopping import Budget, StopReason, stalled

if TYPE_CHECKING:
    from scipy.interpolate import BSpline


N_PARTICLES = 100
"""Swarm size N (paper: 100)."""
N_INTERPOLATED = 100
"""Points M sampled on the B-spline per iteration (paper: "100 control nodes")."""
OMEGA_START, OMEGA_END = 0.9, 0.4
"""Inertia weight, decreasing linearly over the stage."""
C_PERSONAL = C_SOCIAL = 1.49618
"""Learning factors c1, c2 (Clerc's constriction-equivalent values)."""
_COEFFICIENTS = np.array([C_PERSONAL, C_SOCIAL])
VELOCITY_FRACTION = 0.2
"""Velocity clamp as a fraction of the search range."""
SPLINE_DEGREE = 3
CHORD_RTOL = 1e-12
"""Chords shorter than this fraction of the total length count as zero (duplicate particles)."""


def initial_radius(problem: Problem) -> Array:
    """r per unknown: each group's typical error (1 mm for lengths, 1° for angles), (p,)."""
    return problem.model.radius


def initial_swarm(
    problem: Problem, center: Array, n: int, rng: np.random.Generator
) -> Array:
    """N positions ``x_c + r ⊙ (2·rand − 1)`` clipped to the bounds, slot 0 = x_c; shape (n, p)."""
    radius = initial_radius(problem)
    x = center + radius * (2.0 * rng.random((n, center.size)) - 1.0)
    x[0] = center
    return np.clip(x, problem.lower, problem.upper)


def pso_velocity(
    x: Array, v: Array, best_x: Array, g_x: Array, omega: float, vmax: Array, r: Array
) -> Array:
    """Eq. 18's velocity ``ω v + c1 r1 (P − x) + c2 r2 (G − x)``, clamped to ±vmax; shape (N, p).

    Args:
        x: Positions (N, p). v: Velocities (N, p). best_x: Personal bests (N, p).
        g_x: Global best (p,). omega: Inertia weight. vmax: Velocity clamp (p,).
        r: r1 and r2 ~ U(0, 1), per particle and dimension, shape (2, N, p).
    """
    r1, r2 = r
    v = omega * v + C_PERSONAL * r1 * (best_x - x) + C_SOCIAL * r2 * (g_x - x)
    return np.clip(v, -vmax, vmax)


def chord_parameters(x: Array) -> tuple[Array, Array]:
    """Chord-length parameters of the particles in index order (eqs. 20–22).

    Args:
        x: Particles, shape (N, p).

    Returns:
        ``(t, kept)``: parameters in [0, 1], shape (K,), strictly increasing, and the particles
        they belong to, shape (K, p) — a particle equal to its predecessor (zero chord) is dropped.
    """
    chords = np.linalg.norm(np.diff(x, axis=0), axis=1)
    total = float(np.sum(chords))
    keep = np.concatenate(([True], chords > CHORD_RTOL * total))
    t = np.concatenate(([0.0], np.cumsum(chords[keep[1:]])))
    if t[-1] > 0:
        t /= t[-1]
    return t, x[keep]


def _curve(t: Array, kept: Array) -> BSpline:
    """The cubic B-spline with curve(t) = kept, for t of :func:`chord_parameters` (≥ 2 values);
    its degree drops below 3 only when fewer than 4 distinct consecutive particles remain."""
    # Imported here: scipy.interpolate takes about half a second to import, and every command
    # that loads the solver registry would pay it; only the swarm methods need it.
    from scipy.interpolate import make_interp_spline

    # One call for all p dimensions; the particles are finite (clipped to the box), so the
    # finiteness checks, a tenth of the call, are skipped.
    return make_interp_spline(t, kept, k=min(SPLINE_DEGREE, t.size - 1), axis=0,
                              check_finite=False)


def interpolating_curve(x: Array) -> tuple[Array, BSpline]:
    """The cubic B-spline through the particles (eqs. 23–26): ``(t, curve)``, curve(t) = kept x.

    Degree drops below 3 only when fewer than 4 distinct consecutive particles remain.
    """
    t, kept = chord_parameters(x)
    if t.size < 2:
        raise ValueError("the B-spline needs at least two distinct particles")
    return t, _curve(t, kept)


@cache
def _even(m: int) -> Array:
    """M evenly spaced parameters in [0, 1], shape (M,) (read-only: one array per M)."""
    t = np.linspace(0.0, 1.0, m)
    t.setflags(write=False)
    return t


def interpolated_points(x: Array, m: int) -> Array:
    """M points of the curve at evenly spaced parameters in [0, 1] (eq. 27), shape (M, p).

    If all particles coincide the curve is that point. Where the compiled kernels are taken
    (:func:`twin.geometry.kinematics.takes_compiled`) a cubic curve is drawn by
    :func:`twin.solvers.compiled.curve_points`, the same curve to round-off.
    """
    t, kept = chord_parameters(x)
    if t.size < 2:
        return np.repeat(kept[:1], m, axis=0)
    if t.size > SPLINE_DEGREE and takes_compiled():
        from twin.solvers.compiled import curve_points

        return np.asarray(curve_points(t, kept, _even(m)), dtype=np.float64)
    return np.asarray(_curve(t, kept)(_even(m)), dtype=np.float64)


@dataclass
class Swarm:
    """Positions, velocities and personal bests of N particles (mutable; one per run).

    Attributes:
        x: Positions, shape (N, p). v: Velocities, shape (N, p).
        best_x: Personal-best positions, shape (N, p). best_f: Their f, shape (N,), m².
        leader: The slot of G_best, np.argmin of ``best_f``: set where ``best_f`` changes
            (:func:`settle`), read by every move and record of the iteration (four argmins
            and mins an iteration before).
    """

    x: Array
    v: Array
    best_x: Array
    best_f: Array
    leader: int = 0

    def __post_init__(self) -> None:
        self.lead()

    def lead(self) -> None:
        """Find G_best's slot again after ``best_f`` changed."""
        self.leader = int(np.argmin(self.best_f))

    @property
    def g_x(self) -> Array:
        """Global best position G_best, shape (p,)."""
        return self.best_x[self.leader]

    @property
    def g_f(self) -> float:
        """f at G_best, m²."""
        return float(self.best_f[self.leader])


Move = Callable[[Swarm, int], Array]
"""``move(swarm, k) -> candidates (K, p)`` for iteration k (0-based), inside the box; K ≥ N, the
first N are the particles' new positions in slot order (their velocities, if any, already set in
``swarm.v``)."""


def best_in_slots(candidates: Array, f: Array, n: int) -> tuple[Array, Array]:
    """Keep the best n of the candidates, each survivor of the first n in its own slot.

    A moved particle that is among the best n keeps its slot (its velocity and personal best);
    the extra candidates (B-spline points) that are among the best n take the slots of the moved
    particles that are not, in index order.

    Args:
        candidates: Positions (K, p), K ≥ n; the first n are the slots' moved particles.
        f: Their objective, shape (K,).
        n: Number of slots.

    Returns:
        Positions (n, p) and their f (n,).
    """
    chosen = np.argsort(f, kind="stable")[:n]
    newcomers = chosen[chosen >= n]
    survives = np.zeros(n, dtype=bool)
    survives[chosen[chosen < n]] = True
    freed = np.flatnonzero(~survives)  # in index order
    x, fx = candidates[:n].copy(), f[:n].copy()
    x[freed], fx[freed] = candidates[newcomers], f[newcomers]
    return x, fx


def settle(swarm: Swarm, candidates: Array, f: Array, compiled: bool) -> None:
    """The swarm after an iteration: the best N candidates in the slots (:func:`best_in_slots`)
    and the personal bests updated where they improved (elitist), in place; on the compiled
    kernel (``compiled``) in one pass of :func:`twin.solvers.compiled.keep_best`, the same
    numbers.

    Args:
        swarm: The swarm before the iteration's selection.
        candidates: Positions (K, p), the first N the slots' moved particles. f: Their f (K,).
        compiled: Whether to take the compiled kernel.
    """
    n = swarm.x.shape[0]
    if compiled:
        from twin.solvers.compiled import keep_best

        keep_best(candidates, f, np.argsort(f, kind="stable")[:n], swarm.x, swarm.best_x,
                  swarm.best_f)
    else:
        swarm.x, f = best_in_slots(candidates, f, n)
        improved = f < swarm.best_f
        swarm.best_x[improved] = swarm.x[improved]
        swarm.best_f[improved] = f[improved]
    swarm.lead()


def run_population(tracker: Tracker, x_init: Array, budget: Budget, move: Move) -> Outcome:
    """Evaluate, move, select and record a swarm until ``budget`` stops it.

    Args:
        tracker: Evaluates the problem (one batched call per iteration) and records G_best.
        x_init: Initial positions, shape (N, p); slot 0 is the start (the centre).
        budget: Iteration limit and stall test.
        move: Proposes the candidates of each iteration.

    Returns:
        G_best, why the swarm stopped, and whether G_best is better than slot 0's start.
    """
    compiled = takes_compiled()
    f = tracker.cost(x_init)
    f_start = float(f[0])
    swarm = Swarm(x_init.copy(), np.zeros_like(x_init), x_init.copy(), f.copy())
    if not tracker.started:
        tracker.record(swarm.g_x, swarm.g_f)
    best = [swarm.g_f]
    reason = StopReason.MAX_ITERATIONS
    for k in range(budget.max_iterations):
        candidates = move(swarm, k)
        settle(swarm, candidates, tracker.cost(candidates), compiled)
        tracker.record(swarm.g_x, swarm.g_f)
        best.append(swarm.g_f)
        if stalled(best, budget):
            reason = StopReason.STALLED
            break
    return Outcome(swarm.g_x.copy(), reason, moved=swarm.g_f < f_start)


def inertia(k: int, iterations: int) -> float:
    """ω at iteration k of ``iterations``: linear from 0.9 to 0.4."""
    return OMEGA_START - (OMEGA_START - OMEGA_END) * k / max(iterations - 1, 1)


def particle_swarm(
    tracker: Tracker, center: Array, budget: Budget, rng: np.random.Generator,
    n_interpolated: int,
) -> Outcome:
    """Global-best PSO around ``center`` (p,), with the B-spline step if ``n_interpolated`` > 0.

    ``n_interpolated = 0`` is M3 (PSO); ``N_INTERPOLATED`` is M8 (BIPSO): the M curve points are
    pooled with the N moved particles and the best N are kept. Where the compiled kernels are
    taken (:func:`twin.geometry.kinematics.takes_compiled`) an iteration's moves are one call
    of :func:`twin.solvers.compiled.pso_candidates`, with r1 and r2 drawn here as the numpy path
    draws them: the same swarm to round-off.
    """
    problem = tracker.problem
    lower, upper = problem.lower, problem.upper
    vmax = VELOCITY_FRACTION * (upper - lower)
    iterations = budget.max_iterations
    at = _even(n_interpolated)  # none for PSO: read-only alike, one compiled version

    def move(swarm: Swarm, k: int) -> Array:
        r = rng.random((2, *swarm.x.shape))
        omega = inertia(k, iterations)
        if compiled:
            candidates, drawn = pso_candidates(swarm.x, swarm.v, swarm.best_x, swarm.g_x, r,
                                               omega, _COEFFICIENTS, vmax, lower, upper, at,
                                               CHORD_RTOL)
            if not drawn:  # fewer than four distinct particles: scipy's lower degree
                n = swarm.x.shape[0]
                candidates[n:] = np.clip(interpolated_points(candidates[:n], at.size),
                                         lower, upper)
            return np.asarray(candidates, dtype=np.float64)
        swarm.v = pso_velocity(swarm.x, swarm.v, swarm.best_x, swarm.g_x, omega, vmax, r)
        moved = np.clip(swarm.x + swarm.v, lower, upper)
        if n_interpolated == 0:
            return moved
        points = np.clip(interpolated_points(moved, n_interpolated), lower, upper)
        return np.concatenate([moved, points])

    compiled = takes_compiled()
    if compiled:
        from twin.solvers.compiled import pso_candidates
    x_init = initial_swarm(problem, np.asarray(center, dtype=np.float64), N_PARTICLES, rng)
    return run_population(tracker, x_init, budget, move)
