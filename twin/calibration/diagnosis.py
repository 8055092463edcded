"""Why a calibration does not fit its data: the likely causes of a misfit
(:mod:`twin.analysis.misfit`).

Each cause the data could reveal is tried by refitting: the rig's unknowns the calibration left
out (the port, the attachment point, the tracker frame, the length offset, the encoder's
scale) are added one at a time and the problem solved again with LM from the first fit, and
outliers by a Huber fit (scale 3 σ) whose RMSE is taken over the rows it keeps; a cause whose
refit brings the training RMSE within :data:`twin.analysis.misfit.FAR` times the noise is
*likely*, and the refit's RMSE is quoted. Causes no refit can test follow: units (readings whose
scale is far from the nominal model's) and the robot model (joint-level errors, another model
file).
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np

from twin.analysis.misfit import FAR
from twin.calibration.result import CalibrationResult, SplitProblem
from twin.calibration.setup import make_model
from twin.choices import DEFAULT_SCALE_SIGMAS
from twin.dataset import TEMPERATURE
from twin.loss import Loss
from twin.problem import Problem
from twin.report.display import SIGNIFICANT, mm
from twin.solvers import get_solver
from twin.stopping import Budget

REFITS = {
    "port": ("the port positions", "--estimate-port"),
    "attachment": ("the attachment point", "--estimate-attachment"),
    "base": ("the tracker frame", "--estimate-base"),
    "offset": ("the cable's length offset", "--estimate-offset"),
    "scale": ("the encoder's scale", "--estimate-scale"),
}
"""Unknown groups a refit tries: what they stand for and the flag that adds them."""
OUTLIER_SHARE = 0.2
"""A Huber refit that rejects more than this share of the rows does not point at outliers."""
UNITS_RATIO = 2.0
"""Readings whose typical size is more than this factor off the nominal model's (either way)
point at units."""


class Cause(NamedTuple):
    """One likely cause of a misfit."""

    name: str
    """What may be wrong, e.g. ``the port position``."""
    remedy: str
    """What to try."""
    refit_rmse_m: float | None
    """Training RMSE after refitting with it, m; None when no refit tests it."""

    def describe(self) -> str:
        """``the port position (--estimate-port reaches 0.0104 mm)``."""
        if self.refit_rmse_m is None:
            return f"{self.name} ({self.remedy})"
        reaches = mm(self.refit_rmse_m, significant=SIGNIFICANT)
        return f"{self.name} ({self.remedy} reaches {reaches})"


def _refit(split: SplitProblem, result: CalibrationResult, group: str) -> float | None:
    """Training RMSE of LM with ``group`` added (for ``port``: every port, when only some were
    estimated), started from the result; None if the data cannot have that group or the model
    has it already."""
    problem = split.problem
    model, x = problem.model, result.solver.x
    rig = model.rig
    more_ports = group == "port" and model.has("port") \
        and len(rig.estimated_port_index) < len(rig.ports_m)
    if (model.has(group) and not more_ports) \
            or (group not in model.kind.groups and group != "attachment"):
        return None
    wider_rig = replace(rig, estimated_ports=()) if group == "port" else rig
    settings = split.settings
    wider = make_model(model.robot, wider_rig, model.kind.name, replace(
        settings, estimate=(*settings.estimate, group)))
    start = np.zeros(wider.n_params)
    for found in model.groups:
        block = model.block(x, found.name)
        if found.name == "port":
            ports = np.zeros((len(rig.ports_m), 3))
            ports[rig.estimated_port_index] = block.reshape(-1, 3)
            block = ports[wider_rig.estimated_port_index].ravel()
        start[wider.slice(found.name)] = block
    trial = Problem(wider, problem.train, problem.validation, sigma_m=problem.sigma_m,
                    x0=np.clip(start, *wider.bounds()), loss=problem.loss)
    solved = get_solver("lm").solve(trial, Budget(), np.random.default_rng(result.seed))
    return float(np.sqrt(np.mean(wider.residuals(solved.x, problem.train) ** 2)))


def _refit_robust(split: SplitProblem, result: CalibrationResult, noise_m: float
                  ) -> float | None:
    """Training RMSE over the rows a Huber fit (scale 3 σ) from the result keeps; None when it
    rejects more than :data:`OUTLIER_SHARE` of them (then they are not outliers)."""
    problem = split.problem
    trial = replace(problem, x0=result.solver.x,
                    loss=Loss("huber", DEFAULT_SCALE_SIGMAS * noise_m))
    solved = get_solver("lm").solve(trial, Budget(), np.random.default_rng(result.seed))
    residuals = problem.model.residuals(solved.x, problem.train)
    kept = ~trial.loss.rejected(residuals)
    if np.mean(~kept) > OUTLIER_SHARE:
        return None
    return float(np.sqrt(np.mean(residuals[kept] ** 2)))


def _units_suspect(problem: Problem) -> bool:
    """Whether the readings' size is far from the nominal model's
    (:meth:`twin.kinds.base.Kind.units_ratio`)."""
    data, model = problem.train, problem.model
    ratio = model.kind.units_ratio(data, model.residuals(np.zeros(model.n_params), data))
    return ratio is not None and not 1.0 / UNITS_RATIO <= ratio <= UNITS_RATIO


def likely_causes(split: SplitProblem, result: CalibrationResult) -> tuple[Cause, ...]:
    """The likely causes of the result's misfit, most likely first (see the module docstring).
    """
    problem = split.problem
    assert result.misfit is not None
    noise = result.misfit.noise_m
    tried = []
    for group, (name, flag) in REFITS.items():
        rmse = _refit(split, result, group)
        if group == "port" and len(problem.model.rig.ports_m) == 1:
            name = "the port position"
        if rmse is not None:
            tried.append(Cause(name, flag, rmse))
    robust = None if problem.loss.robust else _refit_robust(split, result, noise)
    if robust is not None:
        tried.append(Cause("outliers", "--loss huber", robust))
    tried.sort(key=lambda cause: cause.refit_rmse_m or np.inf)
    likely = [cause for cause in tried if (cause.refit_rmse_m or np.inf) <= FAR * noise]
    rest = [cause for cause in tried if cause not in likely]
    fixed = []
    if _units_suspect(problem):
        fixed.append(Cause("units", "lengths in mm, joint angles in degrees", None))
    if TEMPERATURE in problem.train.values and "thermal" not in split.settings.errors:
        fixed.append(Cause("the links' growth with temperature", "--errors "
                           + ",".join((*split.settings.errors, "thermal")), None))
    fixed.append(Cause("the robot model", "joint-level errors, another model file", None))
    return (*likely, *fixed, *rest)
