"""Calibration results as JSON (mm and degrees), written atomically."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from twin.calibration import CalibrationResult
from twin.io.atomic import write_atomic
from twin.metrics import Metrics
from twin.units import dh_rows_to_display, m_to_mm

MM2_PER_M2 = float(m_to_mm(1.0)) ** 2


def _metrics_mm(m: Metrics) -> dict[str, float]:
    return {key: float(m_to_mm(value)) for key, value in m._asdict().items()}


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
    document.update(
        {
            "metrics": {name: _metrics_mm(m) for name, m in result.metrics.items()},
            "iterations": solver.iterations,
            "evaluations": solver.evaluations,
            "seconds": solver.seconds,
            "converged": solver.converged,
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
