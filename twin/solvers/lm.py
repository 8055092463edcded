"""M2 — Levenberg–Marquardt (paper eq. 9) with Nielsen's damping rule.

Step ``Δx = −(JᵀJ + μI)⁻¹ Jᵀr`` with the analytic Jacobian, in SI units (translational and
angular unknowns then have similar magnitudes, so the isotropic μI is reasonable). The paper gives
no μ schedule; we use Nielsen's (1999): with the gain ratio ρ of actual to predicted decrease,
a step is accepted when ρ > 0 and μ ← μ·max(1/3, 1 − (2ρ − 1)³), else μ ← μ·ν, ν ← 2ν.
Steps are projected onto the bounds (±5 mm / ±8°). Stops when f changes by less than
``budget.ftol_m2`` between accepted iterates, or after ``budget.max_iterations`` iterations.

The loop is shared by the LM variants: a :class:`StepRule` may reshape the damped step before it
is tried (M7 mixes in momentum, M4 picks a step length) and hears whether it was accepted.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from twin.problem import Budget, Problem
from twin.solvers.base import Solver, SolverResult, Tracker

Array = NDArray[np.float64]

TAU = 1e-3
"""Initial damping relative to the largest diagonal entry of JᵀJ (Madsen, Nielsen, Tingleff)."""


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


def free_unknowns(x: Array, gradient: Array, lower: Array, upper: Array) -> NDArray[np.bool_]:
    """Unknowns the next step may move: all but those on a bound that the descent direction
    −gradient pushes outwards (the active set of a bound-constrained least-squares problem).

    Without this, a clipped step keeps pushing into the bound and bends every other component.
    """
    return ~(((x <= lower) & (gradient > 0)) | ((x >= upper) & (gradient < 0)))


def initial_damping(J: Array) -> float:
    """μ₀ = τ · max diag(JᵀJ)."""
    return TAU * float(np.max(np.sum(J * J, axis=0)))


def nielsen(mu: float, nu: float, gain: float) -> tuple[float, float]:
    """Nielsen's update of (μ, ν) after a step with gain ratio ``gain``."""
    if gain > 0:
        return mu * max(1.0 / 3.0, 1.0 - (2.0 * gain - 1.0) ** 3), 2.0
    return mu * nu, 2.0 * nu


def levenberg_marquardt(
    tracker: Tracker,
    x0: Array,
    iterations: int,
    ftol_m2: float,
    rule: StepRule | None = None,
) -> tuple[Array, bool]:
    """Run LM from ``x0`` for at most ``iterations`` iterations, recording each.

    Every tried step is one iteration, accepted or not (as in the paper's iteration counts).

    Args:
        tracker: Evaluates the problem and records the history.
        x0: Start, shape (p,).
        iterations: Iteration budget.
        ftol_m2: Stop when an accepted step changes f by less than this, m².
        rule: Reshapes each damped step (AMLM momentum, VSLM step length); plain LM if None.

    Returns:
        ``(x, converged)``: the last accepted iterate, and whether the f-change rule fired.
    """
    lower, upper = tracker.problem.lower, tracker.problem.upper
    x = np.clip(x0, lower, upper)
    r, J = tracker.jacobian(x)
    f = float(np.mean(r**2))
    if not tracker.history:
        tracker.record(x, f)
    mu, nu = initial_damping(J), 2.0
    for _ in range(iterations):
        step = np.zeros_like(x)
        free = free_unknowns(x, J.T @ r, lower, upper)
        step[free] = damped_step(J[:, free], r, mu)
        if rule is not None:
            step = rule.propose(tracker, x, step)
        x_new = np.clip(x + step, lower, upper)
        h = x_new - x
        predicted = float(r @ r - np.sum((r + J @ h) ** 2))
        clipped = h != step
        while predicted <= 0.0 and np.any(clipped) and rule is None:
            # The projection onto the box spoilt the step: hold the unknowns it clipped at
            # their bound and step in the others (a projected step on the active set; ends,
            # as the free set shrinks each time).
            free &= ~clipped
            step = np.zeros_like(x)
            step[free] = damped_step(J[:, free], r, mu)
            x_new = np.clip(x + step, lower, upper)
            h = x_new - x
            predicted = float(r @ r - np.sum((r + J @ h) ** 2))
            clipped = h != step
        if predicted <= 0.0:
            tracker.record(x, f)
            # Only a reshaped step can point uphill while the LM step still descends: retry.
            if rule is not None and rule.rejected():
                continue
            # A clipped reshaped step: a more damped, shorter one may stay inside and descend.
            if np.any(clipped):
                mu, nu = mu * nu, 2.0 * nu
                continue
            return x, True
        r_new, J_new = tracker.jacobian(x_new)
        f_new = float(np.mean(r_new**2))
        gain = float(r @ r - r_new @ r_new) / predicted
        mu, nu = nielsen(mu, nu, gain)
        if gain > 0:
            if rule is not None:
                rule.accepted(h, f, f_new)
            change = f - f_new
            x, r, J, f = x_new, r_new, J_new, f_new
            tracker.record(x, f)
            if change < ftol_m2:
                return x, True
        else:
            if rule is not None:
                rule.rejected()
            tracker.record(x, f)
    return x, False


def _solve(problem: Problem, budget: Budget, rng: np.random.Generator) -> SolverResult:
    tracker = Tracker(problem, "lm")
    x, converged = levenberg_marquardt(tracker, problem.x0, budget.max_iterations, budget.ftol_m2)
    return tracker.finish(x, converged)


SOLVER = Solver(name="lm", alias="m2", title="Levenberg–Marquardt", solve=_solve)
