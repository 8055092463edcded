"""Calibration results as JSON (mm and degrees), written atomically."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from twin.calibration import CalibrationResult
from twin.identifiability import Identifiability
from twin.io.atomic import write_atomic
from twin.metrics import Metrics
from twin.units import dh_rows_to_display, m_to_mm

MM2_PER_M2 = float(m_to_mm(1.0)) ** 2


def _metrics_mm(m: Metrics) -> dict[str, float]:
    return {key: float(m_to_mm(value)) for key, value in m._asdict().items()}


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
    }


def _finite_or_none(values: list[float]) -> list[float | None]:
    return [v if math.isfinite(v) else None for v in values]


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
        n_dh = result.model.n_dh
        sigma_dh = uncertainty.sigma[:n_dh].reshape(result.model.dh.shape)
        fields["sigma"] = {
            key: _finite_or_none(values) for key, values in dh_rows_to_display(sigma_dh).items()
        }
        if result.model.estimate_port:
            fields["sigma"]["port"] = _finite_or_none(
                m_to_mm(uncertainty.sigma[n_dh : n_dh + 3]).tolist()
            )
        if result.model.estimate_offset:
            fields["sigma"]["offset"] = _finite_or_none([float(m_to_mm(uncertainty.sigma[-1]))])[0]
        fields["noise_sigma"] = float(m_to_mm(uncertainty.noise_sigma_m))
        fields["predicted_flange_rms"] = float(m_to_mm(uncertainty.flange_rms_m))
    return fields


def result_to_dict(result: CalibrationResult) -> dict[str, Any]:
    """The JSON document of one result: lengths in mm, angles in degrees, f in mm²."""
    solver = result.solver
    document: dict[str, Any] = {
        "method": result.method,
        "seed": result.seed,
        "delta": dh_rows_to_display(result.delta),
    }
    if result.model.estimate_port:
        document["port"] = m_to_mm(result.port_m).tolist()
    if result.model.estimate_offset:
        document["offset"] = float(m_to_mm(result.offset_m))
    document.update(_uncertainty_fields(result))
    document.update(
        {
            "metrics": {name: _metrics_mm(m) for name, m in result.metrics.items()},
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
            "history": [
                {
                    "iteration": record.iteration,
                    "f": record.f_m2 * MM2_PER_M2,
                    "rmse": float(m_to_mm(record.train_rmse_m)),
                    "validation_rmse": float(m_to_mm(record.validation_rmse_m)),
                }
                for record in solver.history
            ],
        }
    )
    return document


def write_json(path: str | Path, document: dict[str, Any]) -> None:
    """Write a JSON document atomically."""
    write_atomic(path, json.dumps(document, indent=2) + "\n")
