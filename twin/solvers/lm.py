"""M2 — Levenberg–Marquardt (paper eq. 9) with Nielsen's damping rule, inside the search box.

Step ``Δx = −(JᵀJ + μD)⁻¹ Jᵀr`` with the analytic Jacobian and Marquardt's (1963) scaling
``D = diag(JᵀJ)``: each unknown is damped in proportion to how strongly the data see it. The
paper's eq. 9 writes μI, which damps every unknown alike: on cable data the columns of J span
0.03 (wrist angles) to 0.6 (lengths) for a D-H table, and joint 2's compliance reaches 4.4
(gravity torques of tens of N·m), 2·10⁴× apart in JᵀJ. Under μI the small columns stay damped
until μ has come down by as many orders, which Nielsen's rule does at most threefold per step:
the extended fit (D-H + transmission + backlash + compliance) took 32 Jacobians for what μD
reaches in 15, and the paper's f-change rule fired on that slope (docs/methods.md). Where a
column vanishes (θ6 at the flange centre), the damping is floored at :data:`MU_FLOOR` times
the largest entry of D, so that round-off in Jᵀr along it is never divided by a vanishing
damping. The paper gives no μ schedule; we use Nielsen's (1999): with the gain ratio ρ of
actual to predicted decrease, a step is accepted when ρ > 0 and μ ← μ·max(1/3, 1 − (2ρ − 1)³),
else μ ← μ·ν, ν ← 2ν.

The box (±5 mm / ±8°): when the damped step stays inside it, it is taken as it is; when it
would leave, the step is the exact solution of the damped subproblem on the box,
``min ‖r + J h‖² + μ hᵀD h`` subject to ``lower ≤ x + h ≤ upper`` (bounded-variable least
squares, Stark & Parker's BVLS, as :func:`scipy.optimize.lsq_linear` has it, run on the damped
normal equations: p×p, not m×p), which never predicts an increase. Projecting the
free step instead (clipping it) can point uphill, and deciding afterwards which unknowns were
clipped by comparing the step with its projection is wrong: round-off makes most of them differ
where nothing was clipped (that was this module's bug — it emptied the free set and stopped far
from the optimum, reporting convergence).

Stopping (:mod:`twin.stopping`): first-order optimality (gtol), relative reduction of f (ftol),
relative step (xtol), every unknown held at a bound (bounds), damping at its ceiling
(no_descent), the paper's f-change rule (under ``--stop paper``) or the iteration limit.

JᵀJ and Jᵀr are formed once per Jacobian and serve the step, its box, the gain ratio's
prediction and the stopping tests.

The loop is shared by the LM variants: a :class:`StepRule` may reshape the damped step before it
is tried (M7 mixes in momentum, M4 picks a step length) and hears whether it was accepted; it
gets the step on the box, and what it returns is projected onto the box.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from twin.arrays import Array
from twin.geometry.kinematics import takes_compiled
from twin.problem import Problem
from twin.solvers.base import Outcome, Solver, SolverResult, Tracker
from twin.stopping import Budget, StopReason, held_at_bounds, optimality, small_step

TAU = 1e-3
"""Initial μ: the damping's share of each diagonal entry of JᵀJ (Madsen, Nielsen, Tingleff)."""
MU_FLOOR = 1e-12
"""Smallest μ, and the smallest damping of any unknown relative to the largest diagonal entry
of JᵀJ: along the directions the cable cannot see (θ6 of the IRB 120), Jᵀr is round-off, and
round-off over a vanishing damping would be a step of any size."""
MU_CEILING = 1e16
"""Largest μ: beyond it no step is distinguishable from zero and the run stops with
``no_descent``."""
BOX_RTOL = 1e-10
"""The box step releases an unknown from its bound only when the gradient pushes it inwards by
more than this fraction of the gradient's size (Σ|A_kj h_j| + |g_k|): less is round-off, and
releasing on round-off would cycle."""


class StepRule(Protocol):
    """Turns the damped LM step into the step that is tried, and learns from the outcome."""

    def propose(self, tracker: Tracker, x: Array, step: Array) -> Array:
        """The step to try from ``x`` (p,), given the damped LM step (p,)."""
        ...

    def accepted(self, step: Array, f_old_m2: float, f_new_m2: float) -> None:
        """The applied step (p,) lowered f from ``f_old_m2`` to ``f_new_m2``."""
        ...

    def rejected(self) -> bool:
        """The tried step did not lower f; True if the rule changed something worth a retry."""
        ...


def damping(normal: Array, mu: float) -> Array:
    """The damping μD added to the diagonal of JᵀJ (p, p): shape (p,), μ times each diagonal
    entry, none below :data:`MU_FLOOR` times the largest (module docstring)."""
    diagonal = normal.diagonal()
    return np.maximum(mu * diagonal, MU_FLOOR * float(diagonal.max()))


def damped_step(normal: Array, gradient: Array, damped: Array) -> Array:
    """The LM step −(JᵀJ + diag(damped))⁻¹ Jᵀr, shape (p,), from JᵀJ (p, p), Jᵀr (p,) and the
    damping (p,) of :func:`damping`."""
    A = normal.copy()
    A.flat[:: A.shape[0] + 1] += damped
    return np.asarray(-np.linalg.solve(A, gradient), dtype=np.float64)


def boxed_damped_step(normal: Array, gradient: Array, damped: Array, low: Array, high: Array
                      ) -> Array:
    """The damped step on the box: argmin ‖r + J h‖² + Σ damped_j h_j² with low ≤ h ≤ high,
    shape (p,).

    The same minimiser as ½hᵀAh + gᵀh with A = JᵀJ + diag(damped), g = Jᵀr (p×p, not m×p), found
    by BVLS (Stark & Parker 1995, the algorithm of :func:`scipy.optimize.lsq_linear`): fix
    every unknown whose free minimiser leaves the box at its bound until the free minimiser is
    inside; then release the held unknown the gradient pushes inwards hardest and walk towards
    the new free minimiser, stopping at the first bound in the way, until no held unknown is
    pushed inwards (beyond round-off, :data:`BOX_RTOL`). A is positive definite (damping > 0),
    so the minimiser is unique. Where the compiled kernels are taken
    (:func:`twin.geometry.kinematics.takes_compiled`) the same steps run in
    :func:`twin.solvers.compiled.box_step`, the same minimiser to round-off.

    Args:
        normal: JᵀJ, shape (p, p). gradient: Jᵀr, shape (p,). damped: Damping, all > 0, (p,).
        low: Lower limits of the step (lower − x), shape (p,), all <= 0.
        high: Upper limits of the step (upper − x), shape (p,), all >= 0.
    """
    p = gradient.size
    A = normal.copy()
    A.flat[:: p + 1] += damped
    if takes_compiled():
        from twin.solvers.compiled import box_step

        return np.asarray(box_step(A, gradient, low, high, BOX_RTOL), dtype=np.float64)
    h = np.zeros(p)  # feasible: low <= 0 <= high
    side = np.zeros(p, dtype=np.int8)  # −1 held at low, +1 held at high, 0 free

    def free_minimiser(free: NDArray[np.bool_]) -> Array:
        held = ~free
        rows = A[free]  # rows then columns: np.ix_ costs as much as the solve at p = 24
        # C order, as np.ix_ gave it: the product's round-off depends on the layout
        rhs = -(gradient[free] + np.ascontiguousarray(rows[:, held]) @ h[held])
        # numpy's LU solve: at p ≈ 60 scipy's Cholesky spends 5× longer in its wrappers
        return np.asarray(np.linalg.solve(rows[:, free], rhs), dtype=np.float64)

    free = np.ones(p, dtype=bool)
    while free.any():
        index = np.flatnonzero(free)
        z = free_minimiser(free)
        below, above = z < low[index], z > high[index]
        h[index] = np.clip(z, low[index], high[index])
        side[index[below]], side[index[above]] = -1, 1
        if not (below.any() or above.any()):
            break
        free[index[below | above]] = False
    for _ in range(p):
        inwards = (A @ h + gradient) * side  # > 0 where the bound holds against descent
        k = int(np.argmax(inwards))
        if inwards[k] <= BOX_RTOL * (np.abs(A[k]) @ np.abs(h) + abs(gradient[k])):
            break
        side[k] = 0
        while (side == 0).any():
            free = side == 0
            index = np.flatnonzero(free)
            z, now = free_minimiser(free), h[index]
            below, above = z < low[index], z > high[index]
            if not (below.any() or above.any()):
                h[index] = z
                break
            outside = below | above
            limit = np.where(below, low[index], high[index])
            fraction = np.full(index.size, np.inf)
            fraction[outside] = (limit[outside] - now[outside]) / (z[outside] - now[outside])
            first = int(np.argmin(fraction))
            h[index] = now + fraction[first] * (z - now)
            h[index[first]] = limit[first]
            side[index[first]] = -1 if below[first] else 1
    return np.clip(h, low, high)


def inside(x: Array, lower: Array, upper: Array) -> bool:
    """Whether every unknown is within its bounds (inclusive)."""
    return bool(((x >= lower) & (x <= upper)).all())


def nielsen(mu: float, nu: float, gain: float) -> tuple[float, float]:
    """Nielsen's update of (μ, ν) after a step with gain ratio ``gain``."""
    if gain > 0:
        return mu * max(1.0 / 3.0, 1.0 - (2.0 * gain - 1.0) ** 3), 2.0
    return mu * nu, 2.0 * nu


def _step_on_box(normal: Array, gradient: Array, mu: float, x: Array, lower: Array,
                 upper: Array) -> Array:
    """The damped step (p,) from x (p,) with damping μ (:func:`damping`): as it is when it
    stays inside the box, else :func:`boxed_damped_step`."""
    damped = damping(normal, mu)
    step = damped_step(normal, gradient, damped)
    if inside(x + step, lower, upper):
        return step
    return boxed_damped_step(normal, gradient, damped, lower - x, upper - x)


def levenberg_marquardt(
    tracker: Tracker, x0: Array, budget: Budget, rule: StepRule | None = None
) -> Outcome:
    """Run LM from ``x0`` (p,) until a test of ``budget`` stops it, recording each iteration.

    Every tried step is one iteration, accepted or not (as in the paper's iteration counts).

    Args:
        tracker: Evaluates the problem and records the history.
        x0: Start, shape (p,).
        budget: Iteration limit and stopping tests.
        rule: Reshapes each damped step (AMLM momentum, VSLM step length); plain LM if None.

    Returns:
        The last accepted iterate and the reason the run stopped.
    """
    problem = tracker.problem
    lower, upper, unit = problem.lower, problem.upper, problem.scale
    x = np.clip(x0, lower, upper)
    r, J = tracker.jacobian(x)
    normal, gradient = J.T @ J, J.T @ r
    f = float(np.mean(r**2))
    if not tracker.started:
        tracker.record(x, f)
    mu, nu = TAU, 2.0
    # The damped step on the box at x and μ; kept for a retry without the rule's reshaping
    # (x and μ unchanged: the same step; AMLM under the paper's protocol retries a quarter of
    # its iterations), None once either changes.
    step: Array | None = None
    for _ in range(budget.max_iterations):
        if step is None:
            held = held_at_bounds(x, gradient, lower, upper)
            if held.all():
                return Outcome(x, StopReason.BOUNDS)
            if budget.gtol > 0 and optimality(gradient, normal.diagonal(), float(r @ r),
                                              held) <= budget.gtol:
                return Outcome(x, StopReason.GTOL)
            mu = max(mu, MU_FLOOR)
            step = _step_on_box(normal, gradient, mu, x, lower, upper)
        tried = step if rule is None else rule.propose(tracker, x, step)
        x_new = np.clip(x + tried, lower, upper)
        h = x_new - x
        predicted = float(r @ r - np.sum((r + J @ h) ** 2))
        if predicted <= 0.0:
            tracker.record(x, f)
            # Only a reshaped step can point uphill while the LM step still descends: retry.
            if rule is not None and rule.rejected():
                continue
            step = None
            mu, nu = mu * nu, 2.0 * nu
            if mu > MU_CEILING:
                return Outcome(x, StopReason.NO_DESCENT)
            continue
        step = None
        r_new, J_new = tracker.jacobian(x_new)
        f_new = float(np.mean(r_new**2))
        actual = float(r @ r - r_new @ r_new)
        gain = actual / predicted
        mu, nu = nielsen(mu, nu, gain)
        if gain <= 0:
            if rule is not None:
                rule.rejected()
            tracker.record(x, f)
            if budget.xtol > 0 and small_step(h, x, unit, budget.xtol):
                return Outcome(x, StopReason.XTOL)
            continue
        if rule is not None:
            rule.accepted(h, f, f_new)
        norm_before = float(r @ r)
        x, r, J, f_old, f = x_new, r_new, J_new, f, f_new
        normal, gradient = J.T @ J, J.T @ r
        tracker.record(x, f)
        if budget.ftol > 0 and actual <= budget.ftol * norm_before \
                and predicted <= budget.ftol * norm_before and gain <= 2.0:
            return Outcome(x, StopReason.FTOL)
        if budget.xtol > 0 and small_step(h, x, unit, budget.xtol):
            return Outcome(x, StopReason.XTOL)
        if budget.ftol_m2 > 0 and f_old - f < budget.ftol_m2:
            return Outcome(x, StopReason.F_CHANGE)
    return Outcome(x, StopReason.MAX_ITERATIONS)


def _solve(problem: Problem, budget: Budget, rng: np.random.Generator) -> SolverResult:
    tracker = Tracker(problem, "lm")
    return tracker.finish(levenberg_marquardt(tracker, problem.x0, budget))


SOLVER = Solver(name="lm", title="Levenberg–Marquardt", solve=_solve)
