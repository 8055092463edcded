"""A capture as the command line asks for it: which robot and rig (told by flags, or the
scenario's for a source that simulates the cell), which robot source and encoder, then the
durable capture (:func:`twin.hardware.capture_session.capture_folder`).

Any arm twin calibrates captures: a model file or a URDF of
:data:`~twin.choices.MIN_JOINTS` to :data:`~twin.choices.MAX_JOINTS` joints; the plan's columns
are the robot's ``q1..qN``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, NamedTuple

from twin.choices import MAX_JOINTS, MIN_JOINTS
from twin.errors import InputError
from twin.hardware.capture_session import CAPTURE_NAME, MEASUREMENTS_NAME, capture_folder
from twin.hardware.encoders import resolve
from twin.hardware.encoders.settle import SettleRule
from twin.hardware.robot_sources import SourceRequest, get_source
from twin.robot import RobotModel


@dataclass(frozen=True)
class CaptureRequest:
    """Everything a capture is told.

    Attributes:
        plan: The plan CSV (q1..qN in degrees).
        encoder: A serial URL or a device TOML file.
        out: The capture folder.
        source: How the robot source is opened (its ``plan_q_rad`` is filled in here).
        rule: When a reading counts as settled.
        robot: The nominal robot's file, or None for the IRB 120 (not with a source that
            brings its cell).
        port_mm, attachment_mm: The rig's flags as typed (``X,Y,Z`` mm), or None.
        cable_tension_n: The encoder spring's pull, N, or None.
        scenario, seed: For a source that simulates the cell (sim).
        reconnect_s: How long to try reopening a lost encoder port (None: until it comes back).
    """

    plan: Path
    encoder: str
    out: Path
    source: SourceRequest
    rule: SettleRule
    robot: Path | None = None
    port_mm: str | None = None
    attachment_mm: str | None = None
    cable_tension_n: float | None = None
    scenario: Path | None = None
    seed: int | None = None
    reconnect_s: float | None = 5.0


class CaptureOutcome(NamedTuple):
    """What a capture did."""

    measured: int
    """Poses measured by this run."""
    n_poses: int
    """Poses of the plan."""
    measurements: Path
    """The measurement file."""
    capture: Path
    """The capture file for `twin calibrate`."""


def check_joint_count(robot: RobotModel, source: str | Path) -> None:
    """Refuse an arm outside the joint counts twin models.

    Raises:
        InputError: naming the robot's file.
    """
    if not MIN_JOINTS <= robot.n_joints <= MAX_JOINTS:
        raise InputError(f"a {robot.n_joints}-joint robot",
                         f"a robot of {MIN_JOINTS} to {MAX_JOINTS} joints", source=source)


def _told_cell(request: CaptureRequest) -> tuple[RobotModel, Any, Any]:
    """The robot, rig and calibration settings the flags tell."""
    from twin.calibration.settings import CalibrationSettings
    from twin.io.capture_file import parse_port_mm
    from twin.io.robot_file import load_robot_or_default
    from twin.rig import Rig

    robot = load_robot_or_default(request.robot)
    if request.port_mm is None:
        raise InputError("no --port", "the encoder port as --port X,Y,Z in mm",
                         source="command line")
    rig = Rig.cable(parse_port_mm(request.port_mm, "--port", ""),
                    None if request.attachment_mm is None
                    else parse_port_mm(request.attachment_mm, "--attachment", ""),
                    tension_n=request.cable_tension_n or 0.0)
    calibration = CalibrationSettings() if request.cable_tension_n else None
    return robot, rig, calibration


def capture_request(request: CaptureRequest,
                    report: Callable[[str], None] = print) -> CaptureOutcome:
    """Resolve the robot, rig and source of a capture request and measure its plan durably.

    Raises:
        InputError: on a bad flag, file or combination; CaptureError on a fault mid-capture.
    """
    from twin.io.measurements import load_plan, load_plan_reference

    config = resolve(request.encoder)
    kind = get_source(request.source.spec)
    truth = None
    if kind.cell is not None:
        given = [flag for flag, value in (
            ("--robot", request.robot), ("--port", request.port_mm),
            ("--attachment", request.attachment_mm), ("--cable-tension", request.cable_tension_n))
            if value is not None]
        if given:
            raise InputError(f"{' and '.join(given)} with --robot-source {kind.name}",
                             "none of --robot, --port, --attachment, --cable-tension: the "
                             "scenario gives the robot and the rig", source="command line")
        robot, rig, truth, calibration = kind.cell(request.scenario, request.seed)
    else:
        robot, rig, calibration = _told_cell(request)
    check_joint_count(robot, request.scenario or request.robot or "the IRB 120")
    plan_q_rad, _ = load_plan(request.plan, robot)
    reference = load_plan_reference(request.plan, robot)
    source_request = replace(request.source, plan_q_rad=plan_q_rad,
                             prismatic=tuple(bool(v) for v in robot.prismatic))
    files = kind.files(source_request) if kind.files is not None else {}
    source = kind.open(source_request)
    try:
        measured = capture_folder(request.out, request.plan, plan_q_rad, robot, rig, config,
                                  source, request.rule, calibration=calibration, truth=truth,
                                  source_files=files, reconnect_s=request.reconnect_s,
                                  report=report, reference=reference)
    finally:
        source.close()
    return CaptureOutcome(measured, len(plan_q_rad), request.out / MEASUREMENTS_NAME,
                          request.out / CAPTURE_NAME)
