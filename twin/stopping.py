"""When a method stops, and why: stopping protocols, stop reasons and the convergence tests.

Two protocols:

- ``converge`` (the default): a method runs until a stated test says it has reached a
  stationary point, or until an iteration limit that is a safeguard, not the answer. The tests
  are MINPACK's, on the objective f = mean r² and the unknowns x scaled by their search bounds:
  *ftol* — an accepted step lowered f by less than ``ftol`` (relative) and the linear model
  predicted no more; *xtol* — the step was below ``xtol`` of the unknowns' scale; *gtol* — the
  first-order optimality, the largest cosine between the residual vector and a Jacobian column
  of an unknown not held at a bound, is below ``gtol``. Methods without a gradient (swarms,
  beetle search) stop when their best f has not improved by ``ftol`` (relative) over
  ``stall_iterations`` iterations: *stalled*, which is no proof of an optimum.
- ``paper``: the paper's protocol (method-notes §3), for replicating it: a single-stage method
  stops when f changes by less than 0.001 mm² between iterations (*f_change*) or after 60
  iterations; swarms run all 60; cascades run 30 + 30 with no other test.

Every result names the test that stopped it (:class:`StopReason`); only *ftol*, *xtol* and
*gtol* count as converged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from enum import StrEnum

import numpy as np
from numpy.typing import NDArray

from twin.arrays import Array
from twin.choices import PROTOCOLS
from twin.errors import UnknownChoiceError
from twin.units import mm_to_m

PAPER_FTOL_M2 = float(mm_to_m(1.0) ** 2 * 1e-3)
"""The paper's f-change threshold, 0.001 mm², in m²."""
BOUND_RTOL = 1e-10
"""An unknown within this fraction of its search range from a bound is at the bound."""
COLUMN_RTOL = 1e-8
"""Jacobian columns below this fraction of the largest norm see nothing (θ6 of the IRB 120):
left out of the optimality test, where their cosine would be round-off divided by round-off."""


class StopReason(StrEnum):
    """Why a method (or a stage of a cascade) stopped."""

    FTOL = "ftol"
    XTOL = "xtol"
    GTOL = "gtol"
    F_CHANGE = "f_change"
    STALLED = "stalled"
    MAX_ITERATIONS = "max_iterations"
    BOUNDS = "bounds"
    NO_DESCENT = "no_descent"

    @property
    def converged(self) -> bool:
        """Whether this reason certifies a stationary point (ftol, xtol or gtol)."""
        return self in (StopReason.FTOL, StopReason.XTOL, StopReason.GTOL)

    def describe(self, budget: Budget) -> str:
        """One line for reports, with the thresholds of ``budget``."""
        return {
            StopReason.FTOL: f"converged: f fell by less than {budget.ftol:g} (relative)",
            StopReason.XTOL: f"converged: the step fell below {budget.xtol:g} of the "
                             "unknowns' scale",
            StopReason.GTOL: f"converged: first-order optimality below {budget.gtol:g}",
            StopReason.F_CHANGE: "the paper's rule fired: f changed by less than 0.001 mm²",
            StopReason.STALLED: f"stalled: the best f did not improve by {budget.ftol:g} "
                                f"(relative) in {budget.stall_iterations} iterations",
            StopReason.MAX_ITERATIONS: "stopped at the iteration limit",
            StopReason.BOUNDS: "every unknown is held at a bound: the box, not the data, "
                               "decided",
            StopReason.NO_DESCENT: "no step lowers f any more (damping at its ceiling)",
        }[self]


@dataclass(frozen=True)
class Budget:
    """How long a method runs and which tests stop it (see the module docstring).

    Attributes:
        protocol: ``"converge"`` or ``"paper"``.
        max_iterations: Iteration limit of a single-stage method (paper: 60).
        stage_iterations: Iteration limit of each stage of a cascade (paper: 30).
        ftol: Relative reduction of f below which a step counts as converged; also the
            relative improvement a swarm must make in ``stall_iterations``. 0 switches it off.
        xtol: Relative step size (unknowns scaled by their bounds) below which a method has
            converged; 0 switches it off.
        gtol: First-order optimality below which a method has converged; 0 switches it off.
        stall_iterations: Iterations without improvement after which a gradient-free search
            stops; 0 switches it off (it runs its whole budget).
        ftol_m2: The paper's rule: stop when f changes by less than this, m²; 0 switches it off.
    """

    protocol: str = "converge"
    max_iterations: int = 200
    stage_iterations: int = 200
    ftol: float = 1e-8
    xtol: float = 1e-8
    gtol: float = 1e-8
    stall_iterations: int = 20
    ftol_m2: float = 0.0

    def __post_init__(self) -> None:
        if self.protocol not in PROTOCOLS:
            raise UnknownChoiceError("stopping protocol", self.protocol, PROTOCOLS)
        if self.max_iterations < 1 or self.stage_iterations < 1:
            raise ValueError("iteration limits must be >= 1")
        if self.stall_iterations < 0:
            raise ValueError("stall_iterations must be >= 0")
        for name in ("ftol", "xtol", "gtol", "ftol_m2"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {value}")

    @classmethod
    def paper(cls) -> Budget:
        """The paper's protocol: Δf < 0.001 mm² or 60 iterations; cascades 30 + 30."""
        return cls(protocol="paper", max_iterations=60, stage_iterations=30, ftol=0.0,
                   xtol=0.0, gtol=0.0, stall_iterations=0, ftol_m2=PAPER_FTOL_M2)

    @classmethod
    def named(cls, protocol: str, max_iterations: int | None = None) -> Budget:
        """The budget of a named protocol, optionally with another iteration limit for every
        method and stage.

        Raises:
            UnknownChoiceError: listing the protocols.
        """
        if protocol not in PROTOCOLS:
            raise UnknownChoiceError("stopping protocol", protocol, PROTOCOLS)
        budget = cls.paper() if protocol == "paper" else cls()
        if max_iterations is None:
            return budget
        return replace(budget, max_iterations=max_iterations, stage_iterations=max_iterations)

    def stage(self) -> Budget:
        """The budget of one stage of a cascade: ``stage_iterations``; under the paper's
        protocol the f-change rule is off inside a cascade ("30 times, then 30 times")."""
        return replace(self, max_iterations=self.stage_iterations, ftol_m2=0.0)


def scale(lower: Array, upper: Array) -> Array:
    """The unknowns' scale for the step test: half their search range, shape (p,)."""
    return 0.5 * (upper - lower)


def held_at_bounds(x: Array, gradient: Array, lower: Array, upper: Array) -> NDArray[np.bool_]:
    """Unknowns on a bound that the descent direction −gradient pushes outwards, shape (p,).

    Decided by the bound test with a tolerance of :data:`BOUND_RTOL` of the range — never by
    comparing a step with its projection, which round-off makes differ where nothing was
    clipped.
    """
    tolerance = BOUND_RTOL * (upper - lower)
    return ((x <= lower + tolerance) & (gradient > 0)) | ((x >= upper - tolerance) & (gradient < 0))


def at_bounds(x: Array, lower: Array, upper: Array) -> NDArray[np.bool_]:
    """Unknowns on (within :data:`BOUND_RTOL` of) a bound of their box, shape (p,)."""
    tolerance = BOUND_RTOL * (upper - lower)
    return (x <= lower + tolerance) | (x >= upper - tolerance)


def optimality(gradient: Array, column_squares: Array, residual_square: float,
               held: NDArray[np.bool_]) -> float:
    """First-order optimality: the largest |cos| between r and a column of J, over the unknowns
    not held at a bound and with a column that sees something (MINPACK's gtol measure; units
    cancel column by column), from what LM has formed anyway.

    Args:
        gradient: Jᵀr, shape (p,). column_squares: ‖J_i‖², the diagonal of JᵀJ, shape (p,).
        residual_square: ‖r‖². held: Unknowns held, shape (p,).
    """
    # Array methods and Python floats: LM runs this every iteration, on p ≈ 24 numbers.
    norms = np.sqrt(np.maximum(column_squares, 0.0))
    largest = float(norms.max())
    if residual_square <= 0.0 or not largest > 0.0:
        return 0.0
    counted = ~held & (norms > COLUMN_RTOL * largest)
    if not counted.any():
        return 0.0
    cosines = np.abs(gradient[counted]) / (norms[counted] * math.sqrt(residual_square))
    return float(cosines.max())


def small_step(step: Array, x: Array, unit: Array, xtol: float) -> bool:
    """MINPACK's step test on scaled unknowns: ‖h/s‖ <= xtol (xtol + ‖x/s‖)."""
    return bool(np.linalg.norm(step / unit) <= xtol * (xtol + np.linalg.norm(x / unit)))


def stalled(best_f: list[float], budget: Budget) -> bool:
    """Whether the best f of a gradient-free search improved by less than ``ftol`` (relative)
    over the last ``stall_iterations`` iterations; ``best_f`` is its record, one per iteration."""
    window = budget.stall_iterations
    if window == 0 or len(best_f) <= window:
        return False
    before, now = best_f[-1 - window], best_f[-1]
    return before - now <= budget.ftol * before
