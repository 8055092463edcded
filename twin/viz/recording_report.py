"""The ``report`` document of a recording: metrics table and identifiability, as markdown.

The tables are the CLI's own (:mod:`twin.report.text`), in mm and degrees, inside fenced blocks so
their columns stay aligned; this module adds only what a recording needs beside them.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from twin.analysis.uncertainty import rms_distance
from twin.calibration.result import CalibrationResult
from twin.dataset import Measurements
from twin.kinds import KINDS
from twin.report.display import mm
from twin.report.text import describe_rig, format_comparison, format_result
from twin.rig import Rig
from twin.robot import RobotModel

NO_IDENTIFIABILITY = "Not computed for this run: the results carry no identifiability summary."


def _fenced(text: str) -> str:
    return "```text\n" + text + "\n```"


def flange_error_markdown(
    results: Mapping[str, CalibrationResult], measurements: Measurements,
    truth_delta: NDArray[np.float64],
) -> str:
    """RMS over the measured poses of |P_model − P_true| for the nominal and each identified model.

    This is the comparison that is fair on a rank-deficient problem: it ignores the parameter
    combinations the cable cannot see, which move the flange no more than they move the cable.
    """
    first = next(iter(results.values()))
    true = first.robot.perturbed(truth_delta).flange_positions(measurements.q_rad)
    rows = [("nominal", first.robot)]
    rows += [(name, result.identified_geometry) for name, result in results.items()]
    lines = ["| model | flange error vs truth, RMS [mm] |", "|---|---:|"]
    lines += [
        f"| {label} | "
        f"{mm(rms_distance(robot.flange_positions(measurements.q_rad), true), unit=False)} |"
        for label, robot in rows
    ]
    return "\n".join(lines)


def identifiability_markdown(results: Mapping[str, CalibrationResult]) -> str:
    """What the training poses identify, at the nominal and at each identified geometry.

    Every method of a run shares the training poses and the nominal start, so the nominal
    analysis is the first result's; the analysis at the identified geometry is per method.
    """
    first = next(iter(results.values()))
    nominal = first.identifiability
    if nominal is None:
        return NO_IDENTIFIABILITY
    lines = [
        f"Training poses at the nominal geometry: rank **{nominal.rank} of {nominal.n_params}**, "
        f"condition {nominal.condition:.3g} (column-scaled Jacobian, tolerance "
        f"{nominal.tolerance:g}).",
        "",
        "Not identifiable (arbitrary along these directions: compare flange positions, not raw "
        "parameters): " + (", ".join(f"`{name}`" for name in nominal.unidentifiable) or "none"),
        "",
        "| method | rank at the identified geometry | condition | weak directions |",
        "|---|---:|---:|---:|",
    ]
    lines += [
        f"| {name} | {ident.rank} of {ident.n_params} | {ident.condition:.3g} | {ident.weak} |"
        for name, result in results.items()
        if (ident := result.identified_identifiability) is not None
    ]
    return "\n".join(lines)


def calibration_markdown(
    results: Mapping[str, CalibrationResult],
    measurements: Measurements,
    truth_delta: NDArray[np.float64] | None = None,
) -> str:
    """The report of one calibration run (one or several methods on the same split).

    Args:
        results: Results by method name.
        measurements: Every measured pose.
        truth_delta: True D-H errors, shape (4, n), m and rad, if known.
    """
    first = next(iter(results.values()))
    table = format_result(first, truth_delta) if len(results) == 1 else format_comparison(results)
    parts = [
        f"# Calibration of {first.robot.name}",
        f"{len(measurements)} poses ({first.train_rows.size} train, "
        f"{first.validation_rows.size} validation), seed {first.seed}, "
        f"{describe_rig(first.model.rig, measurements)}. "
        "Residuals and metrics in mm, angles in degrees.",
        "## Metrics",
        _fenced(table),
    ]
    if truth_delta is not None:
        parts += ["## Against the truth", flange_error_markdown(results, measurements, truth_delta)]
    parts += ["## Identifiability", identifiability_markdown(results)]
    return "\n\n".join(parts) + "\n"


def scene_markdown(robot: RobotModel, measurements: Measurements, rig: Rig,
                   truth_delta: NDArray[np.float64] | None = None) -> str:
    """The report of a simulated or captured data set without calibration.

    Args:
        robot: The nominal robot.
        measurements: The poses and readings.
        rig: The rig (ports, attachment).
        truth_delta: True D-H errors, shape (4, n), m and rad, if known.
    """
    parts = [f"# Measurements of {robot.name}",
             f"{len(measurements)} poses, {describe_rig(rig, measurements)}."]
    parts[-1] = parts[-1][:-1] + KINDS.lookup(measurements.kind).summary(measurements) + "."
    if truth_delta is not None:
        rms = rms_distance(robot.flange_positions(measurements.q_rad),
                           robot.perturbed(truth_delta).flange_positions(measurements.q_rad))
        parts.append(f"RMS flange offset of the true robot from the nominal: {mm(rms)}.")
    return "\n\n".join(parts) + "\n"
