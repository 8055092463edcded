"""Capture files (`capture.toml`): what `twin calibrate` needs beside the measurements.

Written by ``twin simulate`` and ``twin capture``; paths are relative to the capture file::

    robot = "robot.toml"              # model file of the nominal robot
    port_mm = [600.0, 300.0, 0.0]     # encoder port, base frame, mm
    measurements = "measurements.csv"
    truth = "truth.json"              # optional: the twin's ground truth
    [calibration]                     # optional: how to calibrate it (flags still override)
    estimate_port = false
    estimate_offset = false
    train_fraction = 0.8
    stop = "converge"                 # or "paper" (twin.stopping)
    max_iterations = 200              # optional: another iteration limit
    errors = ["dh"]                   # the robot's error groups to fit (twin.unknowns.ERRORS)
    cable_tension_n = 0.0             # the cable's pull, N (loads a compliant arm)
    [encoder]                         # optional: how the data was captured
    url = "serial:///dev/ttyUSB0?baud=115200"
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from twin.calibration import TRAIN_FRACTION
from twin.errors import InputError
from twin.io.atomic import write_atomic
from twin.io.paths import read_toml
from twin.io.robot_file import load_robot
from twin.rig import MAX_TENSION_N
from twin.robot import RobotModel
from twin.stopping import MAX_ITERATIONS, PROTOCOLS, Budget
from twin.units import MAX_LENGTH_M, m_to_mm, mm_to_m
from twin.unknowns import ERRORS

_KEYS = ("robot", "port_mm", "measurements", "truth", "calibration", "encoder")


@dataclass(frozen=True)
class CalibrationSettings:
    """How a capture is to be calibrated: which extra unknowns, which split, when to stop.

    Attributes:
        estimate_port: Also identify a correction of the port position.
        estimate_offset: Also identify an unknown cable-length offset.
        train_fraction: Share of the poses used for identification, in (0, 1).
        stop: The stopping protocol, one of :data:`twin.stopping.PROTOCOLS`.
        max_iterations: Iteration limit of every method and stage, or None for the protocol's.
        errors: The robot's error groups to fit, among :data:`twin.unknowns.ERRORS`.
        cable_tension_n: The cable's pull towards the port, N (:attr:`twin.rig.Rig.tension_n`).
    """

    estimate_port: bool = False
    estimate_offset: bool = False
    train_fraction: float = TRAIN_FRACTION
    stop: str = PROTOCOLS[0]
    max_iterations: int | None = None
    errors: tuple[str, ...] = ("dh",)
    cable_tension_n: float = 0.0

    def __post_init__(self) -> None:
        if not 0 < self.train_fraction < 1:
            raise ValueError(f"train_fraction: {self.train_fraction}, expected in (0, 1)")
        if self.stop not in PROTOCOLS:
            raise ValueError(f"stop: {self.stop!r}, expected one of {', '.join(PROTOCOLS)}")
        if self.max_iterations is not None and not 1 <= self.max_iterations <= MAX_ITERATIONS:
            raise ValueError(f"max_iterations: {self.max_iterations}, expected 1 to "
                             f"{MAX_ITERATIONS}")
        object.__setattr__(self, "errors", tuple(self.errors))
        if not self.errors or not set(self.errors) <= set(ERRORS):
            raise ValueError(f"errors: {self.errors!r}, expected groups among "
                             + ", ".join(ERRORS))
        if not (math.isfinite(self.cable_tension_n)
                and 0.0 <= self.cable_tension_n <= MAX_TENSION_N):
            raise ValueError(f"cable_tension_n: {self.cable_tension_n}, expected 0 to "
                             f"{MAX_TENSION_N:g} N")

    @property
    def budget(self) -> Budget:
        """The iteration limits and stopping tests these settings ask for."""
        return Budget.named(self.stop, self.max_iterations)


def _parse_calibration(table: object, source: Path) -> CalibrationSettings:
    if not isinstance(table, dict):
        raise InputError(f"{table!r}", "a table", source=source, where="calibration")
    known = [field.name for field in fields(CalibrationSettings)]
    for key, value in table.items():
        where = f"calibration.{key}"
        if key not in known:
            raise InputError(f"unknown key {key!r}", "only " + ", ".join(known), source=source,
                             where="calibration")
        if key == "train_fraction":
            if isinstance(value, bool) or not isinstance(value, int | float) \
                    or not 0 < value < 1:
                raise InputError(f"{value!r}", "a share in (0, 1)", source=source, where=where)
        elif key == "stop":
            if value not in PROTOCOLS:
                raise InputError(f"{value!r}", "one of " + ", ".join(PROTOCOLS), source=source,
                                 where=where)
        elif key == "max_iterations":
            if isinstance(value, bool) or not isinstance(value, int) \
                    or not 1 <= value <= MAX_ITERATIONS:
                raise InputError(f"{value!r}", f"an integer from 1 to {MAX_ITERATIONS}",
                                 source=source, where=where)
        elif key == "errors":
            if not isinstance(value, list) or not value \
                    or not all(isinstance(name, str) and name in ERRORS for name in value):
                raise InputError(f"{value!r}", "a non-empty list of error groups among "
                                 + ", ".join(ERRORS), source=source, where=where)
        elif key == "cable_tension_n":
            if isinstance(value, bool) or not isinstance(value, int | float) \
                    or not 0 <= value <= MAX_TENSION_N:
                raise InputError(f"{value!r}", f"a tension in N from 0 to {MAX_TENSION_N:g}",
                                 source=source, where=where)
        elif not isinstance(value, bool):
            raise InputError(f"{value!r}", "true or false", source=source, where=where)
    settings = dict(table)
    if "errors" in settings:
        settings["errors"] = tuple(name for name in ERRORS if name in settings["errors"])
    if "cable_tension_n" in settings:
        settings["cable_tension_n"] = float(settings["cable_tension_n"])
    return CalibrationSettings(**settings)


@dataclass(frozen=True)
class Capture:
    """A resolved capture file.

    Attributes:
        path: The capture file.
        robot: The nominal robot it names.
        port_m: Encoder port in the base frame, shape (3,), m.
        measurements: Path of the measurement CSV.
        truth: Path of the ground-truth JSON, or None.
        calibration: The ``[calibration]`` settings (defaults when the table is absent).
        encoder: The ``[encoder]`` table as written, or empty.
    """

    path: Path
    robot: RobotModel
    port_m: NDArray[np.float64]
    measurements: Path
    truth: Path | None = None
    calibration: CalibrationSettings = field(default_factory=CalibrationSettings)
    encoder: dict[str, Any] = field(default_factory=dict)


def parse_port_mm(value: object, source: str | Path, where: str) -> NDArray[np.float64]:
    """Three finite numbers in mm (a list or ``"x,y,z"``) to a port in m, shape (3,)."""
    items: list[Any]
    if isinstance(value, str):
        items = value.split(",")
    elif isinstance(value, list):
        items = value
    else:
        items = [value]
    numbers = []
    for item in items:
        try:
            number = float(item)
        except (TypeError, ValueError):
            number = math.nan
        numbers.append(number)
    largest = float(m_to_mm(MAX_LENGTH_M))
    if len(numbers) != 3 or not all(math.isfinite(n) and abs(n) <= largest for n in numbers):
        raise InputError(f"{value!r}", "three finite numbers X,Y,Z in mm, each within "
                         f"±{largest:.0f}", source=source, where=where)
    return mm_to_m(numbers)


def load_capture(path: str | Path) -> Capture:
    """Read and validate a capture file and the robot it names.

    Raises:
        InputError: naming the key that is wrong.
    """
    path = Path(path)
    document = read_toml(path, "a capture TOML file")
    unknown = sorted(set(document) - set(_KEYS))
    if unknown:
        raise InputError(f"unknown key {unknown[0]!r}", "only " + ", ".join(_KEYS), source=path)
    for key in ("robot", "port_mm", "measurements"):
        if key not in document:
            raise InputError(f"no {key!r}", f"a {key!r} key", source=path)
    for key in ("robot", "measurements", "truth"):
        if key in document and not isinstance(document[key], str):
            raise InputError(f"{document[key]!r}", "a path string", source=path, where=key)
    encoder = document.get("encoder", {})
    if not isinstance(encoder, dict):
        raise InputError(f"{encoder!r}", "a table", source=path, where="encoder")
    folder = path.parent
    return Capture(
        path=path,
        robot=load_robot(folder / document["robot"]),
        port_m=parse_port_mm(document["port_mm"], path, "port_mm"),
        measurements=folder / document["measurements"],
        truth=folder / document["truth"] if "truth" in document else None,
        calibration=_parse_calibration(document.get("calibration", {}), path),
        encoder=encoder,
    )


def write_capture(
    path: str | Path,
    *,
    robot: str,
    port_m: NDArray[np.float64],
    measurements: str,
    truth: str | None = None,
    calibration: CalibrationSettings | None = None,
    encoder: dict[str, str | int | float] | None = None,
) -> None:
    """Write a capture file atomically; ``robot``, ``measurements``, ``truth`` are relative."""
    lines = [
        "# Written by twin; `twin calibrate THIS_FILE` needs nothing else.",
        f"robot = {json.dumps(robot)}",
        "port_mm = [" + ", ".join(repr(float(v)) for v in m_to_mm(port_m)) + "]",
        f"measurements = {json.dumps(measurements)}",
    ]
    if truth is not None:
        lines.append(f"truth = {json.dumps(truth)}")
    if calibration is not None:
        lines += [
            "[calibration]",
            f"estimate_port = {json.dumps(calibration.estimate_port)}",
            f"estimate_offset = {json.dumps(calibration.estimate_offset)}",
            f"train_fraction = {calibration.train_fraction!r}",
            f"stop = {json.dumps(calibration.stop)}",
        ]
        if calibration.max_iterations is not None:
            lines.append(f"max_iterations = {calibration.max_iterations}")
        lines += [f"errors = {json.dumps(list(calibration.errors))}",
                  f"cable_tension_n = {calibration.cable_tension_n!r}"]
    if encoder:
        lines.append("[encoder]")
        lines += [f"{key} = {json.dumps(value)}" for key, value in encoder.items()]
    write_atomic(path, "\n".join(lines) + "\n")
