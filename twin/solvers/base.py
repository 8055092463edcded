"""The one interface every calibration method implements, and the bookkeeping they share.

A method is a :class:`Solver`: a name, a paper alias and a function
``solve(problem, budget, rng) -> SolverResult``. Solvers evaluate the objective only through a
:class:`Tracker`, which counts evaluations, records the per-iteration history (f, train and
validation RMSE) and measures wall time the same way for all of them.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.problem import Budget, Problem

Array = NDArray[np.float64]


class IterationRecord(NamedTuple):
    """State after one iteration (iteration 0 is the start)."""

    iteration: int
    f_m2: float
    """Objective f = mean r² on the training poses, m²."""
    train_rmse_m: float
    """RMSE on the training poses, m."""
    validation_rmse_m: float
    """RMSE on the validation poses, m."""


class SolverResult(NamedTuple):
    """What a method returns."""

    method: str
    x: Array
    """Identified unknowns, shape (p,), m and rad."""
    iterations: int
    evaluations: int
    """Objective evaluations: one per candidate x evaluated on the training poses."""
    jacobians: int
    """Jacobian evaluations."""
    seconds: float
    """Wall time of the solve."""
    converged: bool
    """True if the stopping rule fired before the iteration budget ran out."""
    history: tuple[IterationRecord, ...]


SolveFunction = Callable[[Problem, Budget, np.random.Generator], SolverResult]


@dataclass(frozen=True)
class Solver:
    """A calibration method.

    Attributes:
        name: CLI name, e.g. ``"lm"``.
        alias: The paper's label, e.g. ``"m2"``; empty for methods not in the paper.
        title: Human-readable name.
        solve: ``solve(problem, budget, rng) -> SolverResult``.
    """

    name: str
    alias: str
    title: str
    solve: SolveFunction


class Tracker:
    """Counts evaluations and records the history of one solve."""

    def __init__(self, problem: Problem, method: str) -> None:
        self.problem = problem
        self.method = method
        self.evaluations = 0
        self.jacobians = 0
        self.history: list[IterationRecord] = []
        self._start = time.perf_counter()

    def residuals(self, x: ArrayLike) -> Array:
        """Training residuals for unknowns of shape (..., p): shape (..., m), m."""
        x = np.asarray(x, dtype=np.float64)
        self.evaluations += int(np.prod(x.shape[:-1], dtype=np.int64))
        return self.problem.model.residuals(x, self.problem.train)

    def cost(self, x: ArrayLike) -> Array:
        """Objective f = mean r² for unknowns of shape (..., p): shape (...,), m²."""
        return np.mean(self.residuals(x) ** 2, axis=-1)

    def jacobian(self, x: ArrayLike) -> tuple[Array, Array]:
        """Training residuals (m,) and Jacobian (m, p) at one x of shape (p,).

        Counts as one objective evaluation and one Jacobian evaluation.
        """
        self.evaluations += 1
        self.jacobians += 1
        return self.problem.model.jacobian(x, self.problem.train)

    def record(self, x: ArrayLike, f_m2: float) -> None:
        """Append the state after an iteration; ``f_m2`` is the training objective at x."""
        validation = self.problem.model.residuals(x, self.problem.validation)
        self.history.append(
            IterationRecord(
                iteration=len(self.history),
                f_m2=float(f_m2),
                train_rmse_m=float(np.sqrt(f_m2)),
                validation_rmse_m=float(np.sqrt(np.mean(validation**2))),
            )
        )

    def finish(self, x: ArrayLike, converged: bool) -> SolverResult:
        """The result, with the wall time since the tracker was made."""
        x = np.array(x, dtype=np.float64)
        x.setflags(write=False)
        return SolverResult(
            method=self.method,
            x=x,
            iterations=max(len(self.history) - 1, 0),
            evaluations=self.evaluations,
            jacobians=self.jacobians,
            seconds=time.perf_counter() - self._start,
            converged=converged,
            history=tuple(self.history),
        )
