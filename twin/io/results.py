"""Calibration results as JSON (mm and degrees), written atomically.

Lengths and metrics are rounded to 1e-6 mm, angles to 1e-6 degree and the objective f (mm²) to
6 significant digits: far below any noise, and the file reads back to exactly what it says.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.analysis.drift import Drift
from twin.analysis.identifiability import Identifiability
from twin.analysis.metrics import Metrics
from twin.analysis.misfit import ALPHA
from twin.analysis.steps import ALPHA as STEP_ALPHA
from twin.analysis.workspace import Workspace
from twin.calibration.crossval import CrossValidation
from twin.calibration.result import CalibrationResult
from twin.calibration.selection import ErrorChoice
from twin.geometry.rigid import angles
from twin.io.atomic import write_atomic
from twin.io.robot_file import robot_digest, robot_files
from twin.kinds import Kind
from twin.rig import Rig
from twin.robot import RobotModel
from twin.units import (
    FILE_DEG_DECIMALS,
    FILE_MM_DECIMALS,
    MICRO,
    RESULT_COMPLIANCE_DECIMALS,
    RESULT_MM_DECIMALS,
    dh_rows_rounded,
    m_to_mm,
    rad_to_deg,
    rounded,
    significant,
    to_display,
)

if TYPE_CHECKING:
    from twin.calibration.accuracy import TruthErrors
    from twin.calibration.assessment import Assessment
    from twin.calibration.diagnosis import Cause

MM2_PER_M2 = float(m_to_mm(1.0)) ** 2
MASS_DECIMALS = 3
"""Masses to 1 g, as a robot file keeps them."""


def _mm(values_m: ArrayLike) -> list[float]:
    return rounded(m_to_mm(values_m), RESULT_MM_DECIMALS)


def _ppm(values: ArrayLike) -> list[float]:
    """Scale errors given in m/m, in ppm, as results keep them (1e-4 ppm)."""
    return rounded(np.asarray(values, dtype=np.float64) * MICRO, RESULT_COMPLIANCE_DECIMALS)


def _metrics_mm(m: Metrics) -> dict[str, float]:
    return {key: _mm(value)[0] for key, value in m._asdict().items()}


def robot_to_dict(robot: RobotModel) -> dict[str, Any]:
    """The ``robot`` JSON object: the nominal robot a result was identified for, whole — its
    files as twin writes them (``files``: the model TOML, and the URDF for a URDF robot, with
    every joint, limit, mass, base and tip link) and their digest (``digest``,
    :func:`twin.io.robot_file.robot_digest`), so that the result is usable alone and never
    applied to another robot — and, to read at a glance, the name, parametrisation and nominal
    table (mm, degrees; a Hayati β in degrees), the link masses (kg) and centres of mass (mm)."""
    document: dict[str, Any] = {
        "name": robot.name, "parametrisation": list(robot.structure.parametrisation),
        "digest": robot_digest(robot), "files": robot_files(robot),
        "dh": dh_rows_rounded(robot.dh, RESULT_MM_DECIMALS, is_length=robot.is_length)}
    if robot.mass_kg is not None:
        document["mass_kg"] = rounded(robot.mass_kg, MASS_DECIMALS)
    if robot.com_m is not None:
        document["com_mm"] = np.reshape(_mm(robot.com_m), robot.com_m.shape).tolist()
    return document


def identifiability_to_dict(identifiability: Identifiability, at: str) -> dict[str, Any]:
    """The ``identifiability`` JSON object; ``at`` says where J was evaluated."""
    return {
        "rank": identifiability.rank,
        "parameters": identifiability.n_params,
        "condition": identifiability.condition,
        "tolerance": identifiability.tolerance,
        "weak": identifiability.weak,
        "unidentifiable": list(identifiability.unidentifiable),
        "base": list(identifiability.base_names),
        "at": at,
        **({"beyond_points": list(identifiability.beyond_points)}
           if identifiability.beyond_points else {}),
    }


def _finite_or_none(values: list[float]) -> list[float | None]:
    return [v if math.isfinite(v) else None for v in values]


def _sigma_display(sigma_dh: Any, robot: RobotModel) -> dict[str, list[float]]:
    """Per-parameter σ, shape (4, n), as rounded mm and degrees (nan stays nan)."""
    return dh_rows_rounded(sigma_dh, RESULT_MM_DECIMALS, FILE_DEG_DECIMALS, robot.is_length)


def _uncertainty_fields(result: CalibrationResult) -> dict[str, Any]:
    """``identifiability`` (nominal and identified), ``sigma`` (null: not identifiable), mm/deg."""
    fields: dict[str, Any] = {}
    if result.identifiability is not None:
        fields["identifiability"] = identifiability_to_dict(result.identifiability, "nominal")
    if result.identified_identifiability is not None:
        fields["identifiability_identified"] = identifiability_to_dict(
            result.identified_identifiability, "identified"
        )
    uncertainty = result.uncertainty
    if uncertainty is not None:
        model = result.model
        sigma_dh = model.group("dh").spread(model.block(uncertainty.sigma, "dh")).reshape(
            result.robot.dh.shape)  # 0 where fixed
        fields["sigma"] = {
            key: _finite_or_none(values)
            for key, values in _sigma_display(sigma_dh, result.robot).items()
        }
        if model.has("port"):
            fields["sigma"]["port"] = _finite_or_none(_mm(model.block(uncertainty.sigma, "port")))
        if model.has("offset"):
            sigma_offsets = _finite_or_none(_mm(model.block(uncertainty.sigma, "offset")))
            fields["sigma"]["offset"] = sigma_offsets[0]
            if model.rig.sessions:
                fields["sigma"]["offsets"] = sigma_offsets
        if model.has("scale"):
            fields["sigma"]["scale_ppm"] = _finite_or_none(
                _ppm(model.block(uncertainty.sigma, "scale")))[0]
        fields["noise_sigma"] = _mm(uncertainty.noise_sigma_m)[0]
        fields["predicted_flange_rms"] = _mm(uncertainty.flange_rms_m)[0]
        if result.workspace is not None:
            fields["workspace"] = workspace_to_dict(result.workspace, model.robot.prismatic)
        if model.has("attachment"):
            fields["predicted_point_rms"] = _mm(uncertainty.point_rms_m)[0]
    return fields


def workspace_to_dict(workspace: Workspace, prismatic: NDArray[np.bool_] | None = None
                      ) -> dict[str, Any]:
    """The ``workspace`` JSON object: where the predicted and true flange errors are stated —
    how many poses, within which joint ranges (degrees; a robot with prismatic joints has their
    travels in ``lower_mm``, ``upper_mm`` and nulls for them in the degrees'), covering what."""
    fields: dict[str, Any] = {"poses": len(workspace.q_rad), "covers": workspace.covers}
    sliding = np.zeros(workspace.lower_rad.size, dtype=bool) if prismatic is None else prismatic
    for key, values in (("lower", workspace.lower_rad), ("upper", workspace.upper_rad)):
        fields[f"{key}_deg"] = [None if slides else value for value, slides in zip(
            rounded(rad_to_deg(values), FILE_DEG_DECIMALS), sliding, strict=True)]
    if sliding.any():
        for key, values in (("lower", workspace.lower_rad), ("upper", workspace.upper_rad)):
            fields[f"{key}_mm"] = [value if slides else None for value, slides in zip(
                rounded(m_to_mm(values), FILE_MM_DECIMALS), sliding, strict=True)]
    return fields


def unknowns_to_dict(result: CalibrationResult) -> dict[str, Any]:
    """The ``unknowns`` JSON object: everything needed to rebuild the identified model
    (:func:`twin.io.identified.load_result`) — the measurement kind, the unknown groups, the rig
    the calibration was told, and every unknown's value, unit, σ (null: not identifiable),
    whether it ended on a bound of the search box and whether it lies in a direction held at
    the nominal (its value then the hold's split, not a measurement)."""
    model = result.model
    values, labels = to_display(result.solver.x, model.units)
    sigma = to_display(result.uncertainty.sigma, model.units)[0] \
        if result.uncertainty is not None else [math.nan] * model.n_params
    lower, upper = (to_display(bound, model.units)[0] for bound in model.bounds())
    weight = model.prior_weight()
    prior = to_display(1.0 / np.where(weight > 0, weight, np.inf), model.units)[0]
    held, decided = set(result.at_bounds), set(result.prior_decided)
    split = result.unseen.held(model.names) if result.unseen is not None else frozenset()
    return {
        "kind": model.kind.name,
        "groups": [group.name for group in model.groups],
        "rig": rig_to_dict(model.rig, model.kind),
        "fixed": [name for group in model.groups for name in group.full_names
                  if name not in group.names],
        "parameters": [
            {"name": name, "group": group.name, "value": values[k], "unit": labels[k],
             "sigma": sigma[k] if math.isfinite(sigma[k]) else None,
             "lower": lower[k], "upper": upper[k],
             "prior_sigma": prior[k] if weight[k] > 0 else None,
             "at_bound": name in held, "prior_decided": name in decided,
             "held": name in split}
            for group in model.groups
            for k, name in zip(range(model.n_params)[model.slice(group.name)], group.names,
                               strict=True)
        ],
    }


def limits_to_dict(result: CalibrationResult) -> dict[str, Any]:
    """The ``limits`` JSON object: what the user said may move and how far (the rules as given;
    each unknown's box and prior are in ``unknowns.parameters``)."""
    settings = result.settings
    return {"bounds": [rule.text for rule in settings.bounds],
            "priors": [rule.text for rule in settings.priors],
            "fix": list(settings.fix),
            "default_bounds": "each group's own: the paper's ±5 mm / ±8° for the D-H table"}


def pose_to_list(transform: Any) -> list[float]:
    """A 4×4 transform as ``[x, y, z, rx, ry, rz]`` (mm, degrees; R = Rz Ry Rx), rounded."""
    return [*_mm(transform[:3, 3]),
            *rounded(rad_to_deg(angles(transform[:3, :3])), FILE_DEG_DECIMALS)]


def rig_to_dict(rig: Rig, kind: Kind) -> dict[str, Any]:
    """The rig as the calibration was told it (mm, degrees) for measurements of ``kind``: what
    rebuilds its model. The instrument's frame of readings in one (tracker positions:
    :attr:`twin.kinds.base.Kind.in_instrument_frame`) is kept exactly (16 floats) besides its
    readable pose: it is the rigid fit the calibration started from."""
    document: dict[str, Any] = {
        "ports": {name: _mm(port) for name, port in zip(rig.port_names, rig.ports_m,
                                                         strict=True)},
        "attachment": _mm(rig.attachment_m),
        "tension_n": rig.tension_n,
    }
    if rig.estimated_ports:
        document["estimated_ports"] = list(rig.estimated_ports)
    if rig.unknown_ports:
        document["unknown_ports"] = list(rig.unknown_ports)  # "ports": their starts from the data
    if rig.sessions:
        document["sessions"] = list(rig.sessions)
    if kind.in_instrument_frame:
        document["base_in_tracker"] = {"exact": rig.base_in_tracker.ravel().tolist(),
                                       "pose": pose_to_list(rig.base_in_tracker)}
    if rig.point_names:
        document["points"] = {name: _mm(point) for name, point in zip(
            rig.point_names, rig.points_m, strict=True)}
    if rig.distances:
        document["distances"] = [{"points": [d.first, d.second], "length": _mm(d.length_m)[0]}
                                 for d in rig.distances]
    if rig.angles:
        document["angles"] = [{"planes": [a.first, a.second],
                               "angle_deg": float(np.degrees(a.angle_rad))} for a in rig.angles]
    if rig.part is not None:
        document[kind.name] = rig.part.document()
    if rig.temperature_ref_c is not None:
        document["temperature_ref_c"] = rig.temperature_ref_c
    return document


def noise_to_dict(result: CalibrationResult) -> dict[str, Any]:
    """The ``noise`` JSON object: the noise of a reading the fit used (mm) and how it was
    found, the joints' noise (degrees, one per joint) and, with it, each training row's σ
    (errors in variables, mm: the smallest, median and largest)."""
    settings = result.settings
    row_sigma = result.row_sigma
    return {
        "sigma": _mm(settings.sigma_m)[0],
        "estimated": None if result.noise is None else result.noise.describe(),
        "joint_sigma_deg": rounded(rad_to_deg(settings.joint_sigma_rad), FILE_DEG_DECIMALS),
        "errors_in_variables": row_sigma is not None,
        "row_sigma": None if row_sigma is None else dict(zip(
            ("min", "median", "max"), _mm(np.quantile(row_sigma, [0.0, 0.5, 1.0])),
            strict=True)),
    }


def drift_to_dict(drift: Drift) -> dict[str, Any]:
    """The drift test (:mod:`twin.analysis.drift`): the verdict, the statistic and each
    reference pose's readings (mm, less their mean) against time."""
    unit = drift.time_unit
    return {
        "drift": drift.drift,
        "test": "least-squares slope of each reference pose's readings on time: drift when the "
                f"largest |z| exceeds the two-sided N(0,1) quantile of level {ALPHA:g} / tests",
        "z": significant(drift.statistic),
        "threshold": significant(drift.threshold) if drift.tests else None,
        "tests": drift.tests,
        "noise": _mm(drift.noise_m)[0],
        "noise_source": drift.noise_source,
        "time": "t_s" if drift.timed else "row order",
        "reference_rows": drift.references,
        "series": [{"rows": series.rows.tolist(),
                    f"time_{unit}": series.time_s.tolist(),
                    "readings": [_mm(row) for row in series.reading_m],
                    f"slope_per_{unit}": [significant(value) for value
                                          in m_to_mm(series.slope_m_per_s)],
                    "z": [significant(value) for value in series.z],
                    "moved": _mm(series.drift_m),
                    "spread": _mm(series.spread_m)[0]} for series in drift.series],
    }


def fit_to_dict(result: CalibrationResult, causes: Sequence[Cause] = ()) -> dict[str, Any]:
    """``misfit``, ``loss``, ``rejected_rows`` and ``unobservable`` of a result."""
    document: dict[str, Any] = {"noise": noise_to_dict(result)}
    misfit = result.misfit
    if misfit is not None:
        document["misfit"] = {
            "misfit": misfit.misfit,
            "rmse": _mm(misfit.rmse_m)[0],
            "noise": _mm(misfit.noise_m)[0],
            "noise_source": misfit.noise_source,
            "test": "chi-square of the training residuals against the noise: misfit when "
                    f"chi2 > its {1 - ALPHA:g} quantile",
            "implied_noise": _mm(misfit.implied_sigma_m)[0],
            "chi2": significant(misfit.statistic),
            "dof": misfit.dof,
            "threshold": significant(misfit.threshold),
            "p_value": significant(misfit.p_value),
            "causes": [cause.describe() for cause in causes],
            "steps_found": bool(result.steps),
        }
    if result.drift is not None:
        document["drift"] = drift_to_dict(result.drift)
    document["loss"] = {"name": result.loss.name,
                        "scale": _mm(result.loss.scale_m)[0] if result.loss.robust else None}
    document["rejected_rows"] = result.rejected_rows.tolist()
    document["steps"] = {
        "test": "a step regressor beside the model's Jacobian and a line in the row order, its "
                f"z beyond the normal quantile of {STEP_ALPHA:g} over all places (Bonferroni)",
        "found": [{"row": step.row, "reading_jump": _mm(-step.size_m)[0],
                   "z": significant(abs(step.z))} for step in result.steps],
        "rows": "0-based data rows in the file's order: the first after the jump; reading_jump "
                "in mm, the readings' level after less before against the model"}
    held, unseen = result.held, result.unseen
    if held is not None and unseen is not None:
        document["held_at_nominal"] = {
            "directions": list(unseen.names),
            "rule": "the nominal's null directions the data do not see better than the search "
                    "box (Cramér–Rao σ from the noise estimate above half the box), and every "
                    "exact null direction, held at the nominal: the minimum-norm solution in "
                    "the bound-scaled unknowns, the rig's unknowns taking up the trades",
            "noise": _mm(unseen.noise_m)[0],
            "objective_change": significant(held.cost_change),
            "kept_start": held.kept_start or None,
            "weakly_seen": [{"direction": name, "sigma_of_box": significant(float(sigma))}
                            for name, sigma in zip(unseen.weak_names, unseen.weak_sigma,
                                                   strict=True)],
        }
    gauge = result.gauge
    document["unobservable"] = {"motions": list(gauge.names) if gauge is not None else [],
                                "pin": list(gauge.pins) if gauge is not None else []}
    return document


def truth_to_dict(truth: TruthErrors) -> dict[str, Any]:
    """The errors against the truth over the workspace poses (mm)."""
    return {"flange_error": _mm(truth.flange_m)[0],
            "flange_error_gauge_free": _mm(truth.flange_gauge_free_m)[0],
            "point_error": _mm(truth.point_m)[0],
            "point_error_gauge_free": _mm(truth.point_gauge_free_m)[0],
            "unobservable": list(truth.motions),
            "point_unobservable": list(truth.point_motions)}


def result_to_dict(result: CalibrationResult, *, causes: Sequence[Cause] = (),
                   truth: TruthErrors | None = None) -> dict[str, Any]:
    """The JSON document of one result: lengths in mm, angles in degrees, f in mm².

    Args:
        result: The calibration.
        causes: The likely causes of a misfit, if diagnosed.
        truth: The errors against the truth, if known.
    """
    solver = result.solver
    document: dict[str, Any] = {
        "method": result.method,
        "seed": result.seed,
        "robot": robot_to_dict(result.robot),
        "delta": dh_rows_rounded(result.delta, RESULT_MM_DECIMALS,
                                 is_length=result.robot.is_length),
    }
    if result.model.has("port"):
        document["port"] = _mm(result.port_m)
    if result.model.has("offset"):
        document["offset"] = _mm(result.offset_m)[0]
        if result.model.rig.sessions:
            document["offsets"] = dict(zip(result.model.rig.sessions,
                                           _mm(result.offsets_m), strict=True))
    if result.model.has("scale"):
        document["scale_ppm"] = _ppm(result.scale)[0]
    if result.model.has("attachment"):
        document["attachment"] = _mm(result.attachment_m)
    if result.model.has("base"):
        document["base_in_tracker"] = pose_to_list(result.base_in_tracker)
    if result.model.has("points"):
        document["points"] = {name: _mm(point) for name, point in zip(
            result.model.rig.point_names, result.points_m, strict=True)}
    document.update(fit_to_dict(result, causes))
    if truth is not None:
        document["truth"] = truth_to_dict(truth)
    document["unknowns"] = unknowns_to_dict(result)
    document.update(_uncertainty_fields(result))
    document.update(
        {
            "metrics": {name: _metrics_mm(m) for name, m in result.metrics.items()},
            "validation": {"poses": int(result.validation_rows.size) if not result.held_out
                           else None, "source": result.held_out or "split",
                           "train_poses": int(result.train_rows.size)},
            "iterations": solver.iterations,
            "evaluations": solver.evaluations,
            "seconds": solver.seconds,
            "converged": solver.converged,
            "stop_reason": solver.stop_label,
            "stop": {
                "protocol": result.budget.protocol,
                "stages": [
                    {"method": stage.method, "iterations": stage.iterations,
                     "stop_reason": stage.stop_reason.value}
                    for stage in solver.stages
                ],
            },
            "at_bounds": list(result.at_bounds),
            "prior_decided": list(result.prior_decided),
            "limits": limits_to_dict(result),
            "history": [
                {
                    "iteration": record.iteration,
                    "f": significant(record.f_m2 * MM2_PER_M2),
                    "rmse": _mm(record.train_rmse_m)[0],
                    "validation_rmse": _finite_or_none(_mm(record.validation_rmse_m))[0],
                }
                for record in solver.history
            ],
        }
    )
    return document


def cross_validation_to_dict(crossed: CrossValidation) -> dict[str, Any]:
    """The ``cross_validation`` JSON object: how the folds were made, each fold's held-out
    rows (0-based) and metrics (mm), the pooled metrics and the RMSE over the folds."""
    mean, rms, spread = crossed.rmse_over_folds()
    return {
        "method": crossed.method, "how": crossed.how,
        "folds": [{"label": fold.label, "rows": fold.rows.tolist(),
                   "before": _metrics_mm(fold.before), "held_out": _metrics_mm(fold.held_out),
                   "train": _metrics_mm(fold.train)} for fold in crossed.folds],
        "pooled": _metrics_mm(crossed.pooled),
        "pooled_before": _metrics_mm(crossed.pooled_before),
        "rmse_over_folds": {"mean": _mm(mean)[0], "rms": _mm(rms)[0], "std": _mm(spread)[0]},
    }


def choice_to_dict(choice: ErrorChoice) -> dict[str, Any]:
    """The ``error_choice`` JSON object of ``--errors auto``: the rule and every candidate's
    unknowns, rank, BIC and residuals (mm), the chosen one marked."""
    return {
        "rule": "lowest BIC = m ln(RSS/m) + k ln m, m training residuals, k the rank at the "
                "nominal geometry",
        "candidates": [
            {"errors": list(candidate.errors), "unknowns": candidate.unknowns,
             "rank": candidate.rank, "bic": significant(candidate.bic),
             "train_rmse": _mm(candidate.result.metrics["train"].rmse)[0],
             "validation_rmse": _mm(candidate.result.metrics["validation"].rmse)[0]
             if candidate.result.validated else None,
             "chosen": k == choice.chosen}
            for k, candidate in enumerate(choice.candidates)],
        "skipped": list(choice.skipped),
    }


def assessment_to_dict(assessment: Assessment, sigma_mm: float,
                       truth: TruthErrors | None = None) -> dict[str, Any]:
    """The JSON document of `twin identify`: the nominal identifiability and observability, the
    Cramér–Rao bound at the noise assumed (``sigma_mm``) — of the flange, null when the data do
    not pin it, and then of the measured point — and the calibration."""
    nominal, score = assessment.nominal, assessment.score
    point = assessment.point_bound_m
    return {
        "poses": len(assessment.data),
        "nominal": {
            **identifiability_to_dict(nominal, "nominal"),
            "observability": score.observability._asdict(),
            "workspace": workspace_to_dict(assessment.workspace,
                                           assessment.result.model.robot.prismatic),
            "cramer_rao_flange_rms": rounded(m_to_mm(score.flange_rms_m),
                                             RESULT_MM_DECIMALS)[0]
            if assessment.pinned else None,
            "cramer_rao_point_rms": None if point is None
            else rounded(m_to_mm(point), RESULT_MM_DECIMALS)[0],
            "sigma_assumed": sigma_mm,
        },
        "calibration": result_to_dict(assessment.result, truth=truth),
    }


def write_json(path: str | Path, document: dict[str, Any]) -> None:
    """Write a JSON document atomically."""
    write_atomic(path, json.dumps(document, indent=2) + "\n")
