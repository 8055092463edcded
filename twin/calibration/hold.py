"""Every method's answer made safe to leave the tool: the unseen directions at the start, and
never a model worse than the start.

1. **Hold.** The components of x along what the training poses cannot see at the answer
   (:mod:`twin.analysis.unseen`: below the rank threshold, or with a Cramér–Rao σ from the
   fit's noise estimate wider than the box) are set to the start's, the minimum-norm solution
   in the bound-scaled unknowns, the rig taking up what trades with it. Along exact null directions
   this changes no residual; along barely seen ones it changes them by about the noise, and a short
   polish within the seen directions (Gauss–Newton on ``r(x_held + P z) − r(x_method)``: it restores
   the method's own residuals, it does not optimise further, so a method's result is judged as
   it found it) takes that back. What holding costs — the change of the training objective —
   is reported.
2. **Not worse than the start.** The method's point is kept only when it explains the training
   data better than the start by more than fitting its seen combinations to noise would:
   by the Bayesian information criterion of :mod:`twin.calibration.selection`,
   ``m ln(RSS / m) + k ln m`` with k the rank, against the start's with k = 0. Otherwise the
   start is returned, with the reason (a swarm that stalled next to its start, a filter that
   wandered).

Both apply alike to local, Kalman, swarm and cascade methods: they act on the answer, not on
the search.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from twin.analysis.identifiability import Identifiability
from twin.analysis.misfit import chi2_quantile
from twin.analysis.uncertainty import residual_sigma
from twin.analysis.unseen import (
    SIGNIFICANCE_LEVEL,
    Unseen,
    unseen_directions,
    unseen_with_weak,
)
from twin.arrays import Array
from twin.problem import Problem
from twin.report.display import mm2

POLISH_ITERATIONS = 3
"""Gauss–Newton steps of the polish: the residuals it restores are a second-order change."""
POLISH_RTOL = 1e-6
"""The polish stops when what a further step could still restore is below this fraction of the
residuals' size (:func:`_polish`)."""
KEPT_RTOL = 1e-10
"""Singular values of the kept unknowns' rows of P below this (of the largest) count as zero:
those combinations of the seen directions move no kept unknown."""
HOLD_ITERATIONS = 10
"""Rounds of hold and polish; one for directions that stay put (θ6 of a flange-centre cable)."""
HOLD_ATOL = 1e-6
"""What may be left along the unseen directions, in bound-scaled units: a millionth of the box
(5 nm of ±5 mm, 0.03″ of ±8°), below anything a result shows, and far above the round-off a
further round cannot remove. At 1e-12, the round-off itself, a plane's hold chased it through
all its rounds (2.1e-8 left after the first, then 2.8e-12, 3.7e-12, 4.0e-12 …) and every hold
of a fixture's fixed points took a second round (a polish and a look, 2 ms) to remove ~1e-8."""


class Held(NamedTuple):
    """What holding the unseen directions did to a method's answer."""

    x: Array
    """The answer held at the start along the unseen directions, shape (p,)."""
    unseen: Unseen
    """What the training poses cannot see at the method's answer."""
    method_x: Array
    """The method's own answer, before it was held, shape (p,)."""
    moved: Array
    """How far each unseen direction was moved back, in the hold's weighted units
    (:attr:`twin.analysis.unseen.Unseen.scale`), shape (k,)."""
    f_before_m2: float
    """The training objective of the method's own answer, m²."""
    f_after_m2: float
    """The training objective of the held answer, m²."""
    kept_start: str
    """Why the start was returned instead of the method's point, or empty."""

    @property
    def cost_change(self) -> float:
        """Relative change of the training objective, (f_after − f_before) / f_before."""
        return (self.f_after_m2 - self.f_before_m2) / self.f_before_m2 \
            if self.f_before_m2 > 0 else 0.0


def _objective(problem: Problem, x: Array) -> tuple[Array, float]:
    """The training rows at x (p,), each scaled to the noise of a reading
    (:meth:`twin.problem.Problem.data_residuals`), and their mean cost f, m² — what the data
    say, without the priors: the data's fit is what the start is compared with."""
    residuals = problem.data_residuals(x)
    return residuals, float(np.mean(problem.loss.cost(residuals)))


def _seen_step(jacobian: Array, gap: Array, x: Array, seen_x: Array, lower: Array,
               upper: Array) -> Array:
    """The Gauss–Newton step (p,) within the seen directions P (p, q) that takes the residuals'
    ``gap`` (m,) back at x (p,), with J the Jacobian (m, p): the unknowns it would push out of
    the box are kept where they are, and the step taken again without them.

    Clipping the step instead undid it at an answer on a bound: the polish gave up, and the
    hold cost the training objective 11 % (a leave-one-session-out fold of the MuKCa Panda,
    a6 and d6 on their bound), by an amount that changed with the BLAS's rounding (0.3305,
    0.3458 and 0.3486 mm on three of OpenBLAS's kernels)."""
    basis = seen_x
    kept = np.zeros(x.size, dtype=bool)
    for _ in range(x.size):
        step = basis @ np.linalg.lstsq(jacobian @ basis, -gap, rcond=None)[0]
        out = ((x + step < lower) | (x + step > upper)) & ~kept
        if not out.any():
            return step
        kept |= out
        # The directions of P that leave every kept unknown where it is.
        _, singular, rows = np.linalg.svd(seen_x[kept], full_matrices=True)
        rank = int(np.sum(singular > KEPT_RTOL * float(singular[0])))
        basis = seen_x @ rows[rank:].T
        if not basis.shape[1]:
            break
    return np.zeros_like(x)


def _polish(problem: Problem, x: Array, target: Array, seen_x: Array) -> Array:
    """x moved within the seen directions P (p, q) so that the training residuals come back to
    ``target``, inside the search box.

    A Gauss–Newton step leaves its predicted gap orthogonal to what the seen directions reach,
    so a further step can restore at most about the part of the new gap the linear model did
    not predict. Holding moves the residuals along the unseen directions too, which no seen
    step restores: the gap settles on that, most often after one step. The polish stops when
    that bound is below :data:`POLISH_RTOL` of the residuals. (A stop when the gap itself fell
    below 1e-12 of the residuals never fired there: 76 polishes of the geometric study's first
    40 trials took 220 steps, the second and third mostly changing the gap by under 1e-3 of
    itself; 137 with this stop, 0.5 ms less per trial.)"""
    lower, upper = problem.lower, problem.upper
    size = float(np.linalg.norm(target))
    for _ in range(POLISH_ITERATIONS):
        residuals, jacobian = problem.data_jacobian(x)
        gap = residuals - target
        step = _seen_step(jacobian, gap, x, seen_x, lower, upper)
        moved = np.clip(x + step, lower, upper)
        change = problem.data_residuals(moved) - target
        if np.linalg.norm(change) >= np.linalg.norm(gap):
            break
        predicted = gap + jacobian @ (moved - x)
        x = moved
        if np.linalg.norm(change - predicted) <= POLISH_RTOL * size:
            break
    return x


def _bic(f_m2: float, rows: int, rank: int) -> float:
    """m ln(f) + k ln m (f = RSS / m, the training objective)."""
    return rows * math.log(max(f_m2, 1e-300)) + rank * math.log(rows)


def rows_chi2(f_change_m2: float, rows: int, noise_m: float) -> float:
    """A change of the training objective f (the mean over ``rows`` rows) as χ²: m Δf / σ²."""
    return rows * f_change_m2 / noise_m**2


def _unseen(problem: Problem, x: Array, noise: float, nominal: Identifiability,
            start: Array | None) -> Unseen:
    """What the training poses cannot see at x (and the weak directions x does not tell from
    the start, when ``start`` is given), unnamed: :func:`_hold` reads the subspace alone."""
    return unseen_directions(problem.model, x, problem.train, noise, problem.scale, nominal,
                             _row_weight(problem), start, named=False)


def _row_weight(problem: Problem) -> Array | None:
    """The training rows' weights where they differ (errors in variables), else None: rows of
    weight 1 linearise as every other check's at that point (the answer's identifiability
    reads the hold's last look: :mod:`twin.analysis.linearisation` keeps them by weight)."""
    return problem.train_weight if problem.in_variables else None


def _hold(problem: Problem, x: Array, target: Array, unseen: Unseen, noise: float,
          nominal: Identifiability, start: Array | None) -> Array:
    """x held at the start along ``unseen`` (what :func:`_unseen` gives at x), and restored to
    the method's residuals ``target`` within the seen directions."""
    held, along = x, unseen
    # Where the data trade unknowns nonlinearly (an eyelet's turn about the flange axis for
    # θ6), the unseen directions turn with x: hold, restore, and look again, until nothing is
    # left along the unseen directions of the point reached.
    for _ in range(HOLD_ITERATIONS):
        if not along.basis.shape[1] \
                or np.max(np.abs(along.along(held - problem.x0))) <= HOLD_ATOL:
            break
        held = np.clip(problem.x0 + along.remove(held - problem.x0), problem.lower,
                       problem.upper)
        held = _polish(problem, held, target, along.seen_x)
        along = _unseen(problem, held, noise, nominal, start)
    return held


def hold_unseen(problem: Problem, x: Array, nominal: Identifiability) -> Held:
    """The method's answer ``x`` (p,) held at the start along the unseen directions, or the
    start itself when the answer does not beat it (module docstring).

    Args:
        problem: The problem the method solved (its start ``x0`` is where x is held).
        x: The method's answer, shape (p,).
        nominal: What the training poses identify at the start geometry: the candidates of
            the unseen directions, and its rank the noise estimate's and the BIC's k.
    """
    x = np.asarray(x, dtype=np.float64)
    start = problem.x0
    target, f_method = _objective(problem, x)
    rank = nominal.rank
    # The noise of the rows the loss keeps: outliers a robust loss rejects are not noise.
    kept = target[~problem.loss.rejected(target)] if problem.loss.robust else target
    noise = residual_sigma(kept, rank) if kept.size > rank else 0.0
    # What the answer cannot see, and that with the weak directions it does not tell from the
    # start: one factorisation of its Jacobian for both.
    unseen, weak_unseen = unseen_with_weak(problem.model, x, problem.train, noise, problem.scale,
                                           nominal, _row_weight(problem), start)
    held = _hold(problem, x, target, unseen, noise, nominal, None)
    _, f_held = _objective(problem, held)
    extra = weak_unseen.basis.shape[1] - unseen.basis.shape[1]
    if extra > 0 and noise > 0:
        # Holding the weak directions too is taken only if the data cannot tell: the fit it
        # costs is within what that many directions fitted to noise would give (a likelihood
        # ratio at the tests' level).
        weak_held = _hold(problem, x, target, weak_unseen, noise, nominal, start)
        _, f_weak = _objective(problem, weak_held)
        if rows_chi2(f_weak - f_held, target.size, noise) \
                < chi2_quantile(1 - SIGNIFICANCE_LEVEL, extra):
            unseen, held, f_held = weak_unseen, weak_held, f_weak
    moved = unseen.along(x - start)
    _, f_start = _objective(problem, start)
    rows = target.size
    if _bic(f_start, rows, 0) <= _bic(f_held, rows, rank):
        reason = (f"the answer's training objective ({mm2(f_held)}) does not beat the start's "
                  f"({mm2(f_start)}) by more than fitting {rank} combinations to noise would "
                  "(BIC)")
        return Held(np.array(start), unseen, x, moved, f_method, f_start, reason)
    return Held(held, unseen, x, moved, f_method, f_held, "")


__all__ = ["Held", "hold_unseen"]
