"""The one interface every calibration method implements, and the bookkeeping they share.

A method is a :class:`Solver`: a name, a title and a function
``solve(problem, budget, rng) -> SolverResult``. Solvers evaluate the objective only through a
:class:`Tracker`, which counts evaluations, records the per-iteration history (f, train and
validation RMSE) and measures wall time the same way for all of them. Every run, and every
stage of a cascade, ends with a :class:`~twin.stopping.StopReason` that says which test
stopped it.

The validation RMSE of the history is no part of any method (they never see the validation
poses): the tracker keeps each iteration's x and evaluates them all at the end, in batches
(the model is vectorised over x), which gives the same numbers as one evaluation per iteration
at a fraction of the cost.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from twin.arrays import Array
from twin.problem import Problem
from twin.stopping import Budget, StopReason

HISTORY_BATCH = 64
"""Iterates whose validation residuals the tracker evaluates in one call: batched, but with
bounded memory on runs of thousands of iterations."""


class IterationRecord(NamedTuple):
    """State after one iteration (iteration 0 is the start)."""

    iteration: int
    f_m2: float
    """Objective f on the training poses, m²: mean r² (with a robust loss, the mean row cost;
    with unequal row variances or priors, of the objective's rows, :mod:`twin.problem`)."""
    train_rmse_m: float
    """√f, m: the RMSE on the training poses for plain least squares."""
    validation_rmse_m: float
    """RMSE on the validation poses, m; NaN without validation poses."""


class Outcome(NamedTuple):
    """Where one run or stage ended and why."""

    x: Array
    """The unknowns it returns, shape (p,), m and rad."""
    reason: StopReason
    """The test that stopped it."""
    moved: bool = True
    """False if it returns its start unchanged (a search that found nothing better)."""


class StageResult(NamedTuple):
    """One stage of a method: a single-stage method has one, a cascade two."""

    method: str
    iterations: int
    stop_reason: StopReason


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
    stop_reason: StopReason
    """Why the (last stage of the) method stopped."""
    converged: bool
    """True if x is a point where a convergence test (ftol, xtol, gtol) fired."""
    stages: tuple[StageResult, ...]
    """Each stage's name, iterations and stop reason, in order."""
    history: tuple[IterationRecord, ...]

    @property
    def stop_label(self) -> str:
        """The stop reasons of the stages joined by ``+``, e.g. ``gtol+stalled``."""
        return "+".join(stage.stop_reason.value for stage in self.stages)


SolveFunction = Callable[[Problem, Budget, np.random.Generator], SolverResult]


@dataclass(frozen=True)
class Solver:
    """A calibration method.

    Attributes:
        name: CLI name, e.g. ``"lm"`` (the paper's label, ``"m2"``, is the registry's alias:
            :data:`twin.solvers.SOLVERS`).
        title: Human-readable name.
        solve: ``solve(problem, budget, rng) -> SolverResult``.
    """

    name: str
    title: str
    solve: SolveFunction


class Tracker:
    """Counts evaluations and records the history of one solve."""

    def __init__(self, problem: Problem, method: str) -> None:
        self.problem = problem
        self.method = method
        self.evaluations = 0
        self.jacobians = 0
        self._x: list[Array] = []
        self._f: list[float] = []
        self._start = time.perf_counter()

    def residuals(self, x: ArrayLike) -> Array:
        """The objective's rows for unknowns of shape (..., p): shape (..., R), m
        (:meth:`twin.problem.Problem.residuals`: the training rows, then the prior rows)."""
        x = np.asarray(x, dtype=np.float64)
        self.evaluations += math.prod(x.shape[:-1])
        return self.problem.residuals(x)

    def cost(self, x: ArrayLike) -> Array:
        """Objective f, the mean of the rows' costs, for unknowns of shape (..., p): shape
        (...,), m² (:meth:`twin.problem.Problem.objective`)."""
        x = np.asarray(x, dtype=np.float64)
        self.evaluations += math.prod(x.shape[:-1])
        return self.problem.objective(x)

    def jacobian(self, x: ArrayLike) -> tuple[Array, Array]:
        """The rows least squares iterates on at one x of shape (p,): the objective's rows (R,)
        and Jacobian (R, p), the training rows reweighted by the problem's loss
        (:meth:`twin.problem.Problem.loss_rows`; unchanged for least squares), so that
        mean(rows²) = f.

        Counts as one objective evaluation and one Jacobian evaluation.
        """
        return self.problem.loss_rows(*self.model_jacobian(x))

    def model_jacobian(self, x: ArrayLike) -> tuple[Array, Array]:
        """The objective's rows (R,) and their Jacobian (R, p) at one x, before the loss;
        counted as :meth:`jacobian`."""
        self.evaluations += 1
        self.jacobians += 1
        return self.problem.jacobian(x)

    def record(self, x: ArrayLike, f_m2: float) -> None:
        """Append the state after an iteration; ``f_m2`` is the training objective at x (p,).
        Its validation RMSE is computed when the result is made (module docstring)."""
        self._x.append(np.array(x, dtype=np.float64))
        self._f.append(float(f_m2))

    @property
    def started(self) -> bool:
        """Whether the start (iteration 0) is recorded: a cascade's second stage goes on from
        the first's history."""
        return bool(self._f)

    @property
    def iterations(self) -> int:
        """Iterations recorded so far (the start is iteration 0)."""
        return max(len(self._f) - 1, 0)

    @property
    def history(self) -> tuple[IterationRecord, ...]:
        """The recorded iterations, with the validation RMSE of each x (evaluated on each
        access)."""
        model, validation = self.problem.model, self.problem.validation
        rmse: list[float] = [] if len(validation) else [float("nan")] * len(self._x)
        for start in range(0, len(self._x) if len(validation) else 0, HISTORY_BATCH):
            residuals = model.residuals(np.stack(self._x[start:start + HISTORY_BATCH]),
                                        validation)
            rmse.extend(np.sqrt(np.mean(residuals**2, axis=-1)).tolist())
        return tuple(
            IterationRecord(iteration=k, f_m2=f, train_rmse_m=float(np.sqrt(f)),
                            validation_rmse_m=value)
            for k, (f, value) in enumerate(zip(self._f, rmse, strict=True))
        )

    def finish(self, outcome: Outcome) -> SolverResult:
        """The result of a single-stage method, with the wall time since the tracker was made."""
        stage = StageResult(self.method, self.iterations, outcome.reason)
        return self.finish_stages(outcome, [stage], converged=outcome.reason.converged)

    def finish_stages(self, outcome: Outcome, stages: list[StageResult], converged: bool
                      ) -> SolverResult:
        """The result of a method whose stages are given, with the wall time so far (the
        history's validation RMSEs included)."""
        x = np.array(outcome.x, dtype=np.float64)
        x.setflags(write=False)
        history = self.history
        return SolverResult(
            method=self.method,
            x=x,
            iterations=self.iterations,
            evaluations=self.evaluations,
            jacobians=self.jacobians,
            seconds=time.perf_counter() - self._start,
            stop_reason=outcome.reason,
            converged=converged,
            stages=tuple(stages),
            history=history,
        )
