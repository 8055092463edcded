"""M2 — Levenberg–Marquardt (paper eq. 9) with Nielsen's damping rule, inside the search box.

Step ``Δx = −(JᵀJ + μI)⁻¹ Jᵀr`` with the analytic Jacobian, in SI units (translational and
angular unknowns then have similar magnitudes, so the isotropic μI is reasonable). The paper gives
no μ schedule; we use Nielsen's (1999): with the gain ratio ρ of actual to predicted decrease,
a step is accepted when ρ > 0 and μ ← μ·max(1/3, 1 − (2ρ − 1)³), else μ ← μ·ν, ν ← 2ν.

The box (±5 mm / ±8°): when the damped step stays inside it, it is taken as it is; when it
would leave, the step is the exact solution of the damped subproblem on the box,
``min ‖r + J h‖² + μ‖h‖²`` subject to ``lower ≤ x + h ≤ upper`` (bounded-variable least
squares, :func:`scipy.optimize.lsq_linear`), which never predicts an increase. Projecting the
free step instead (clipping it) can point uphill, and deciding afterwards which unknowns were
clipped by comparing the step with its projection is wrong: round-off makes most of them differ
where nothing was clipped (that was this module's bug — it emptied the free set and stopped far
from the optimum, reporting convergence).

Stopping (:mod:`twin.stopping`): first-order optimality (gtol), relative reduction of f (ftol),
relative step (xtol), every unknown held at a bound (bounds), damping at its ceiling
(no_descent), the paper's f-change rule (under ``--stop paper``) or the iteration limit.

The loop is shared by the LM variants: a :class:`StepRule` may reshape the damped step before it
is tried (M7 mixes in momentum, M4 picks a step length) and hears whether it was accepted; it
gets the step on the box, and what it returns is projected onto the box.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import solve_triangular
from scipy.optimize import lsq_linear

from twin.problem import Problem
from twin.solvers.base import Outcome, Solver, SolverResult, Tracker
from twin.stopping import Budget, StopReason, held_at_bounds, optimality, small_step

Array = NDArray[np.float64]

TAU = 1e-3
"""Initial damping relative to the largest diagonal entry of JᵀJ (Madsen, Nielsen, Tingleff)."""
MU_FLOOR = 1e-12
"""Smallest damping relative to the largest diagonal entry of JᵀJ: along the directions the
cable cannot see (θ6 of the IRB 120), Jᵀr is round-off, and round-off over a vanishing μ
would be a step of any size."""
MU_CEILING = 1e16
"""Largest damping relative to the largest diagonal entry of JᵀJ: beyond it no step is
distinguishable from zero and the run stops with ``no_descent``."""


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


def damped_step(J: Array, r: Array, mu: float) -> Array:
    """The LM step −(JᵀJ + μI)⁻¹ Jᵀr, shape (p,)."""
    A = J.T @ J
    A[np.diag_indices_from(A)] += mu
    return np.asarray(-np.linalg.solve(A, J.T @ r), dtype=np.float64)


def boxed_damped_step(J: Array, r: Array, mu: float, low: Array, high: Array) -> Array:
    """The damped step on the box: argmin ‖r + J h‖² + μ‖h‖² with low ≤ h ≤ high, shape (p,).

    Args:
        J: Jacobian (m, p). r: Residuals (m,). mu: Damping μ > 0.
        low: Lower limits of the step (lower − x), shape (p,), all <= 0.
        high: Upper limits of the step (upper − x), shape (p,), all >= 0.
    """
    # ‖r + J h‖² + μ‖h‖² = ‖Lᵀh + L⁻¹Jᵀr‖² + const with JᵀJ + μI = L Lᵀ: the same minimiser
    # from a p×p system instead of the (m + p)×p augmented one, m/p times less work for the
    # bounded solver (the unbounded step solves the same normal equations).
    A = J.T @ J
    A[np.diag_indices_from(A)] += mu
    L = np.linalg.cholesky(A)
    target = -solve_triangular(L, J.T @ r, lower=True)
    # lsq_linear needs low < high strictly; an unknown exactly at a bound still has room
    # on the other side.
    solved = lsq_linear(L.T, target, bounds=(low, high), method="bvls", tol=1e-14)
    return np.clip(np.asarray(solved.x, dtype=np.float64), low, high)


def inside(x: Array, lower: Array, upper: Array) -> bool:
    """Whether every unknown is within its bounds (inclusive)."""
    return bool(np.all((x >= lower) & (x <= upper)))


def initial_damping(J: Array) -> float:
    """μ₀ = τ · max diag(JᵀJ)."""
    return TAU * float(np.max(np.sum(J * J, axis=0)))


def nielsen(mu: float, nu: float, gain: float) -> tuple[float, float]:
    """Nielsen's update of (μ, ν) after a step with gain ratio ``gain``."""
    if gain > 0:
        return mu * max(1.0 / 3.0, 1.0 - (2.0 * gain - 1.0) ** 3), 2.0
    return mu * nu, 2.0 * nu


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
    f = float(np.mean(r**2))
    if not tracker.started:
        tracker.record(x, f)
    largest = float(np.max(np.sum(J * J, axis=0)))
    mu, nu = initial_damping(J), 2.0
    for _ in range(budget.max_iterations):
        held = held_at_bounds(x, J.T @ r, lower, upper)
        if np.all(held):
            return Outcome(x, StopReason.BOUNDS)
        if budget.gtol > 0 and optimality(J, r, held) <= budget.gtol:
            return Outcome(x, StopReason.GTOL)
        mu = max(mu, MU_FLOOR * largest)
        step = damped_step(J, r, mu)
        if not inside(x + step, lower, upper):
            step = boxed_damped_step(J, r, mu, lower - x, upper - x)
        if rule is not None:
            step = rule.propose(tracker, x, step)
        x_new = np.clip(x + step, lower, upper)
        h = x_new - x
        predicted = float(r @ r - np.sum((r + J @ h) ** 2))
        if predicted <= 0.0:
            tracker.record(x, f)
            # Only a reshaped step can point uphill while the LM step still descends: retry.
            if rule is not None and rule.rejected():
                continue
            mu, nu = mu * nu, 2.0 * nu
            if mu > MU_CEILING * largest:
                return Outcome(x, StopReason.NO_DESCENT)
            continue
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
        largest = float(np.max(np.sum(J * J, axis=0)))
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


SOLVER = Solver(name="lm", alias="m2", title="Levenberg–Marquardt", solve=_solve)
