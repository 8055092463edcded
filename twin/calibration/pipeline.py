"""Calibration end to end: split the measurements, run a method, measure the result.

This is the Python API the CLI mirrors::

    robot = twin.default_robot()
    data = twin.load_measurements("measurements.csv")
    result = twin.calibrate(robot, data, port_m=[0.6, 0.3, 0.0], method="lm", seed=0)
    result.metrics["validation"].rmse      # m
    result.identified_geometry.dh          # (4, 6), m and rad
    result.solver.stop_reason              # which test stopped the method

How it is set up is :mod:`twin.calibration.setup` (from one
:class:`~twin.calibration.settings.CalibrationSettings`), what it returns
:mod:`twin.calibration.result`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.analysis.drift import Drift, has_reference_rows, reference_drift
from twin.analysis.gauge import Gauge, unobservable_motions
from twin.analysis.identifiability import Identifiability, measurement_identifiability
from twin.analysis.linearisation import model_jacobian
from twin.analysis.metrics import Metrics, metrics
from twin.analysis.misfit import Misfit, misfit_test, repeat_sigma
from twin.analysis.steps import Step, find_steps
from twin.analysis.uncertainty import calibration_uncertainty
from twin.analysis.workspace import Workspace, data_workspace
from twin.arrays import Array
from twin.calibration.held_out import held_out_residuals
from twin.calibration.hold import Held, hold_unseen
from twin.calibration.result import CalibrationResult, SplitProblem
from twin.calibration.settings import CalibrationSettings
from twin.calibration.setup import DEFAULT_SETTINGS, make_problem
from twin.dataset import Measurements, joined
from twin.problem import Problem
from twin.rig import Rig
from twin.robot import RobotModel
from twin.solvers import Solver, SolverResult, get_solver
from twin.stopping import Budget


def calibrate_many(
    robot: RobotModel,
    measurements: Measurements,
    port_m: ArrayLike | None,
    methods: Sequence[str],
    *,
    rig: Rig | None = None,
    settings: CalibrationSettings = DEFAULT_SETTINGS,
    seed: int = 0,
    on_result: Callable[[CalibrationResult], None] | None = None,
    report: bool = True,
) -> dict[str, CalibrationResult]:
    """Run several methods on the same split, each with a generator seeded from ``seed``.

    Takes the arguments of :func:`calibrate`, with a list of methods, ``on_result``, called
    with each method's result as soon as it is done (to show a run live), and ``report``
    (:func:`solve_many`).

    Returns:
        Results keyed by each method's name, in the order given.
    """
    split = make_problem(robot, measurements, port_m, rig=rig, settings=settings, seed=seed)
    return solve_many(robot, split, methods, seed=seed, on_result=on_result, report=report)


def rejected_poses(problem: Problem, x: ArrayLike, data: Measurements) -> NDArray[np.bool_]:
    """Which poses of ``data`` have a residual row the problem's loss rejects, shape (m,)."""
    return _rejected(problem, problem.model.residuals(np.asarray(x, dtype=np.float64), data),
                     len(data))


def _rejected(problem: Problem, residuals: Array, poses: int) -> NDArray[np.bool_]:
    """Which of ``poses`` poses have a row of ``residuals`` (their kind's rows, then any rows
    of no pose) the problem's loss rejects, shape (poses,)."""
    rows = problem.model.kind.rows_per_pose
    beyond = problem.loss.rejected(residuals[: rows * poses])
    return np.asarray(np.any(beyond.reshape(poses, rows), axis=1))


def _assess(split: SplitProblem, x: Array, train_residuals: Array, identified: Identifiability,
            q_workspace: Array
            ) -> tuple[Misfit, NDArray[np.intp], Measurements, Array | None, Gauge]:
    """The fit test, the rejected rows, the training poses kept (and their rows' weights σ/σ_i
    when they differ) and the unobservable motions, from the training residuals at x."""
    problem, train_rows, validation_rows = split.problem, split.train_rows, split.validation_rows
    out_train = _rejected(problem, train_residuals, len(problem.train))
    # Rows of the measurements: a separate file's rejected rows are not among them.
    out_validation = rejected_poses(problem, x, problem.validation) if not split.held_out \
        else np.zeros(0, dtype=bool)
    rejected = np.sort(np.concatenate([train_rows[out_train], validation_rows[out_validation]]))
    rows = problem.model.kind.rows_per_pose
    # A loss that rejects nearly everything (a swarm far from the optimum) leaves no degree of
    # freedom to test or to estimate the noise from: then every training row counts.
    enough = rows * int(np.sum(~out_train)) > identified.rank
    if enough and np.any(out_train):
        kept = problem.train.subset(np.flatnonzero(~out_train))
        residuals = problem.model.residuals(x, kept)
    else:
        kept, residuals = problem.train, train_residuals
    row_sigma = problem.row_sigma(kept) if problem.in_variables else None
    misfit = misfit_test(residuals, identified.rank, problem.sigma_m,
                         repeat_sigma(kept, residuals, rows), row_sigma)
    gauge = unobservable_motions(problem.model, x, identified.null_space, q_workspace)
    weight = None if row_sigma is None else problem.sigma_m / row_sigma
    return misfit, rejected.astype(np.intp), kept, weight, gauge


def _drift(split: SplitProblem) -> Drift | None:
    """The drift test of the reference rows of the measurements (train and validation, in
    their order) at the start's unknowns; None without reference rows."""
    problem = split.problem
    validated = not split.held_out and len(problem.validation) > 0
    if not has_reference_rows(problem.train) \
            and not (validated and has_reference_rows(problem.validation)):
        return None  # nothing to join, order and evaluate
    data, rows = problem.train, split.train_rows
    if validated:
        data = joined(data, problem.validation)
        rows = np.concatenate([rows, split.validation_rows])
    order = np.argsort(rows, kind="stable")
    data = data.subset(order)
    drift = reference_drift(data, problem.model.residuals(problem.x0, data),
                            problem.model.kind.rows_per_pose, problem.sigma_m)
    if drift is None:
        return None
    return drift._replace(series=tuple(series._replace(rows=rows[order][series.rows])
                                       for series in drift.series))


def _steps(split: SplitProblem, problem: Problem, x: Array) -> tuple[Step, ...]:
    """The steps of the residuals over every row of the measurements, in their order (the
    training and the split's validation rows; a separate file's are not among them), for kinds
    of one row per pose."""
    if problem.model.kind.rows_per_pose != 1:
        return ()
    parts = [(split.train_rows, problem.train)]
    if not split.held_out:
        parts.append((split.validation_rows, problem.validation))
    residuals = np.zeros(sum(len(rows) for rows, _ in parts))
    jacobian = np.zeros((residuals.size, problem.model.n_params))
    for rows, data in parts:
        if len(rows):
            r, j = model_jacobian(problem.model, x, data)  # the training rows' as linearised
            residuals[rows], jacobian[rows] = r[: len(rows)], j[: len(rows)]
    return find_steps(residuals, problem.sigma_m, jacobian)


def _metrics(problem: Problem, x: Array, train_residuals: Array) -> dict[str, Metrics]:
    """``before`` (the start on the validation poses, or on the training poses when there are
    none), ``train`` (of the training residuals at x) and, when there are validation poses,
    ``validation`` (:func:`twin.calibration.held_out.held_out_residuals`)."""
    model, train, validation = problem.model, problem.train, problem.validation
    trained = metrics(train_residuals)
    if not len(validation):
        return {"before": metrics(model.residuals(problem.x0, train)), "train": trained}
    return {"before": metrics(held_out_residuals(model, problem.x0, train, validation)),
            "train": trained,
            "validation": metrics(held_out_residuals(model, x, train, validation))}


RELINEARISE_RTOL = 1e-3
"""With errors in variables, a method is run again when the rows' weights at its first answer
differ from those at the start by more than this fraction."""


def _solve(solver: Solver, problem: Problem, budget: Budget, seed: int,
           nominal: Identifiability) -> tuple[Problem, SolverResult, Held]:
    """The method's answer, held along the unseen directions; with errors in variables, solved
    once more with the rows' variances taken at that answer (the joints' Jacobians g_i move
    with the geometry, method-notes §7), when they changed. Returns the problem the answer
    solves, the answer and what holding did."""
    solved = solver.solve(problem, budget, np.random.default_rng(seed))
    held = hold_unseen(problem, solved.x, nominal)
    if problem.in_variables:
        again = replace(problem, linearised_at=held.x)
        if np.max(np.abs(again.train_weight / problem.train_weight - 1.0)) > RELINEARISE_RTOL:
            problem = again
            solved = solver.solve(problem, budget, np.random.default_rng(seed))
            held = hold_unseen(problem, solved.x, nominal)
    return problem, solved._replace(x=held.x), held


def solve_many(
    robot: RobotModel,
    split: SplitProblem,
    methods: Sequence[str],
    *,
    seed: int = 0,
    on_result: Callable[[CalibrationResult], None] | None = None,
    report: bool = True,
) -> dict[str, CalibrationResult]:
    """:func:`calibrate_many` on a problem already made (and so already checked) by
    :func:`make_problem`. With ``report=False`` each result holds the answer, its metrics, the
    hold and the identifiability at the start and at the answer, which is all a study's trial
    reads; the checks a report shows beside them (the fit test and the rejected rows, the
    gauge, the uncertainty over the workspace, the steps, the drift) are left out (None, or
    empty): 15 % of a study trial's CPU."""
    solvers = [get_solver(name) for name in methods]
    nominal = measurement_identifiability(split.problem.model, split.problem.x0,
                                          split.problem.train)
    workspace = data_workspace(split.problem.train.q_rad, np.random.default_rng(seed)) \
        if report else None
    drift = _drift(split) if report else None
    results = {}
    for solver in solvers:
        problem, solved, held = _solve(solver, split.problem, split.settings.budget, seed,
                                       nominal)
        identified = measurement_identifiability(problem.model, solved.x, problem.train)
        # The training rows at the answer, once for the rejections, the fit test and the metrics.
        train_residuals = problem.model.residuals(solved.x, problem.train)
        checks = {} if workspace is None else _checks(
            split._replace(problem=problem), solved.x, train_residuals, nominal, identified,
            held, workspace)
        results[solver.name] = CalibrationResult(
            robot=robot, model=problem.model, solver=solved, seed=seed,
            train_rows=split.train_rows, validation_rows=split.validation_rows,
            metrics=_metrics(problem, solved.x, train_residuals),
            identifiability=nominal,
            identified_identifiability=identified,
            settings=split.settings,
            unseen=held.unseen,
            held=held,
            held_out=split.held_out,
            noise=split.noise,
            row_sigma=problem.row_sigma(problem.train) if problem.in_variables else None,
            drift=drift,
            **checks,
        )
        if on_result is not None:
            on_result(results[solver.name])
    return results


def _checks(split: SplitProblem, x: Array, train_residuals: Array, nominal: Identifiability,
            identified: Identifiability, held: Held, workspace: Workspace) -> dict[str, Any]:
    """The checks a report shows beside a method's answer x (:func:`solve_many`), as the
    :class:`CalibrationResult` fields they fill."""
    problem = split.problem
    misfit, rejected, kept, weight, gauge = _assess(split, x, train_residuals, identified,
                                                    workspace.q_rad)
    return {
        "uncertainty": calibration_uncertainty(problem.model, x, kept, nominal.rank,
                                               workspace.q_rad, held.unseen, weight),
        # A σ fitted to these residuals explains them by construction: no misfit test.
        "misfit": None if split.noise is not None and split.noise.from_residuals else misfit,
        "rejected_rows": rejected,
        "gauge": gauge,
        "workspace": workspace,
        "steps": _steps(split, problem, x),
    }


def calibrate(
    robot: RobotModel,
    measurements: Measurements,
    port_m: ArrayLike | None = None,
    *,
    rig: Rig | None = None,
    method: str = "lm",
    settings: CalibrationSettings = DEFAULT_SETTINGS,
    seed: int = 0,
) -> CalibrationResult:
    """Identify the errors of ``robot`` (and the rig's unknowns) from measurements.

    ``robot``, ``measurements``, ``port_m`` (or ``rig``) and ``settings`` are those of
    :func:`twin.calibration.setup.make_problem`.

    Args:
        method: A method name or paper alias (``lm``, ``m2``, …).
        settings: What to estimate and how: the error groups, the rig's unknowns, the noise,
            the loss, the stopping protocol (run to convergence by default; ``stop="paper"``
            is the paper's protocol), the split.
        seed: Seed of the train/validation split and of any random draw of the method.
    """
    return calibrate_many(robot, measurements, port_m, [method], rig=rig, settings=settings,
                          seed=seed)[get_solver(method).name]
