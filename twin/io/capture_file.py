"""Capture files (`capture.toml`): what `twin calibrate` needs beside the measurements.

Written by ``twin simulate`` and ``twin capture``; paths are relative to the capture file::

    robot = "robot.toml"              # model file of the nominal robot
    port_mm = [600.0, 300.0, 0.0]     # encoder port, base frame, mm (cable lengths);
                                      # "unknown": nobody measured it (found from the data)
    measurements = "measurements.csv"
    truth = "truth.json"              # optional: the twin's ground truth
    [ports]                           # optional, instead of port_mm: several named ports (the
    front = [600.0, -400.0, 100.0]    # measurement CSV's port column names each row's)
    left = [500.0, 500.0, 0.0]
    [rig]                             # optional
    attachment_mm = [0.0, 0.0, 40.0]  # the measured point in the flange frame (default 0,0,0)
    distances = ["f1s1,f1s2=50"]      # known distances between fixed points (or planes), mm
    angles = ["top,front=90"]         # known angles between planes, degrees
    [calibration]                     # optional: how to calibrate it (flags still override):
    errors = ["dh"]                   # the keys of twin.io.calibration_table, and
    cable_tension_n = 0.0             # the cable's pull, N (loads a compliant arm)
    [encoder]                         # optional: how the data was captured
    url = "serial:///dev/ttyUSB0?baud=115200"
    sigma_mm = 0.01                   # the instrument's noise 1σ (misfit test, filters)
    resolution_mm = 0.004             # its resolution
    repeatability_mm = 0.01           # the robot's RMS flange repeatability (noise of a pose)
    sigma_deg = 0.01                  # a 6-D instrument's angle noise 1σ, degrees
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from twin.analysis.misfit import reading_sigma
from twin.calibration.settings import CalibrationSettings
from twin.choices import MAX_TENSION_N
from twin.errors import InputError
from twin.io.atomic import write_atomic
from twin.io.calibration_table import KEYS, calibration_lines, parse_calibration
from twin.io.paths import read_toml
from twin.io.robot_file import load_robot
from twin.io.table import Table
from twin.problem import DEFAULT_SIGMA_M
from twin.rig import Angle, Distance, Rig
from twin.robot import RobotModel
from twin.units import MAX_LENGTH_M, deg_to_rad, m_to_mm, mm_to_m

_KEYS = ("robot", "port_mm", "measurements", "truth", "calibration", "encoder", "ports", "rig")
_RIG_KEYS = ("attachment_mm", "distances", "angles")


@dataclass(frozen=True)
class Capture:
    """A resolved capture file.

    Attributes:
        path: The capture file.
        robot: The nominal robot it names.
        port_m: Encoder port in the base frame, shape (3,), m; the first of several, None
            without one (tracker positions, fixed points).
        measurements: Path of the measurement CSV.
        truth: Path of the ground-truth JSON, or None.
        calibration: The ``[calibration]`` settings (defaults when the table is absent), their
            noise the ``[encoder]``'s (:attr:`reading_sigma_m`).
        encoder: The ``[encoder]`` table as written, or empty.
        rig: The rig it names: ports (``port_mm`` or ``[ports]``), attachment, distances, and
            the cable tension of ``[calibration] cable_tension_n``.
    """

    path: Path
    robot: RobotModel
    port_m: NDArray[np.float64] | None
    measurements: Path
    truth: Path | None = None
    calibration: CalibrationSettings = field(default_factory=CalibrationSettings)
    encoder: dict[str, Any] = field(default_factory=dict)
    rig: Rig = field(default_factory=Rig)

    @property
    def instrument_sigma_m(self) -> float:
        """The instrument's noise the capture states: ``[encoder]`` sigma_mm with its
        resolution's res²/12 folded in, m; the default 0.01 mm when it states none."""
        sigma = float(mm_to_m(self.encoder.get("sigma_mm", 0.0)))
        resolution = float(mm_to_m(self.encoder.get("resolution_mm", 0.0)))
        total = math.hypot(sigma, resolution / math.sqrt(12.0))
        return total if total > 0 else DEFAULT_SIGMA_M

    @property
    def angle_sigma_rad(self) -> float | None:
        """The instrument's angle noise the capture states (``[encoder]`` sigma_deg), rad;
        None when it states none."""
        sigma = float(deg_to_rad(self.encoder.get("sigma_deg", 0.0)))
        return sigma if sigma > 0 else None

    @property
    def repeatability_m(self) -> float:
        """The robot's RMS flange repeatability the capture states (``[encoder]``
        repeatability_mm), m; 0 when it states none."""
        return float(mm_to_m(self.encoder.get("repeatability_mm", 0.0)))

    @property
    def reading_sigma_m(self) -> float:
        """The noise 1σ of one reading: the instrument's and the robot's repeatability
        (:func:`twin.analysis.misfit.reading_sigma`), m."""
        return reading_sigma(self.instrument_sigma_m, self.repeatability_m)


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
    document = Table(read_toml(path, "a capture TOML file"), path, allowed=_KEYS)
    files = {key: document.text(key, expected="a path, relative to the capture file")
             for key in ("robot", "measurements", "truth")
             if key != "truth" or document.has(key)}
    encoder = document.table("encoder")
    for key in ("sigma_mm", "resolution_mm", "repeatability_mm"):
        encoder.number(key, 0.0, minimum=0.0, expected="a noise in mm >= 0")
    encoder.number("sigma_deg", 0.0, minimum=0.0, maximum=90.0,
                   expected="an angle noise in degrees, 0 to 90")
    folder = path.parent
    table = document.table("calibration", allowed=(*KEYS, "cable_tension_n"))
    rig = replace(_parse_rig(document), tension_n=table.number(
        "cable_tension_n", 0.0, minimum=0.0, maximum=MAX_TENSION_N,
        expected=f"a tension in N from 0 to {MAX_TENSION_N:g}"))
    capture = Capture(
        path=path,
        robot=load_robot(folder / files["robot"]),
        port_m=rig.ports_m[0] if len(rig.ports_m) else None,
        measurements=folder / files["measurements"],
        truth=folder / files["truth"] if "truth" in files else None,
        encoder=dict(encoder.values),
        rig=rig,
    )
    return replace(capture, calibration=parse_calibration(
        table, capture.reading_sigma_m, sigma_rad=capture.angle_sigma_rad))


def _parse_pair(value: object, valid: Callable[[float], bool], expected: str,
                source: str | Path, where: str) -> tuple[str, str, float]:
    """``"A,B=NUMBER"``: two different names and a number ``valid`` accepts, as written."""
    text = value if isinstance(value, str) else ""
    names, _, number = text.partition("=")
    first, _, second = (name.strip() for name in names.partition(","))
    try:
        size = float(number)
    except ValueError:
        size = math.nan
    if not (first and second and first != second and math.isfinite(size) and valid(size)):
        raise InputError(f"{value!r}", expected, source=source, where=where)
    return first, second, size


def parse_distance(value: object, source: str | Path, where: str) -> Distance:
    """``"A,B=MM"``: a known distance between the fixed points A and B, mm, to SI."""
    first, second, length_mm = _parse_pair(
        value, lambda size: 0 < size <= float(m_to_mm(MAX_LENGTH_M)),
        "A,B=MM: two different point names and a distance in mm > 0", source, where)
    return Distance(first, second, float(mm_to_m(length_mm)))


def parse_distances(values: list[Any], source: str | Path, where: str = ""
                    ) -> tuple[Distance, ...]:
    """Known distances ``"A,B=MM"`` (:func:`parse_distance`), each pair of points once: a pair
    told twice is two answers to one question (and A,B and B,A are one pair).

    Args:
        values: The ``A,B=MM`` texts.
        source: The file or flag they come from.
        where: Where the list is in the file (``[rig] distances``), or "" for a flag.
    """
    return _parse_pairs(values, parse_distance, lambda d: f"{float(m_to_mm(d.length_m)):g} mm",
                        "points", source, where)


def parse_angle(value: object, source: str | Path, where: str) -> Angle:
    """``"A,B=DEG"``: a known angle between the planes A and B, degrees, to SI."""
    first, second, angle_deg = _parse_pair(
        value, lambda size: 1 <= size <= 179, "A,B=DEG: two different plane names and the "
        "angle between their normals, 1 to 179 degrees (parallel planes: a distance)",
        source, where)
    return Angle(first, second, float(deg_to_rad(angle_deg)))


def parse_angles(values: list[Any], source: str | Path, where: str = "") -> tuple[Angle, ...]:
    """Known angles ``"A,B=DEG"`` (:func:`parse_angle`), each pair of planes once.

    Args:
        values: The ``A,B=DEG`` texts.
        source: The file or flag they come from.
        where: Where the list is in the file (``[rig] angles``), or "" for a flag.
    """
    return _parse_pairs(values, parse_angle, lambda a: f"{math.degrees(a.angle_rad):g} deg",
                        "planes", source, where)


_Pair = TypeVar("_Pair", Distance, Angle)


def _parse_pairs(values: list[Any], parse: Callable[[object, str | Path, str], _Pair],
                 shown: Callable[[_Pair], str], what: str, source: str | Path, where: str
                 ) -> tuple[_Pair, ...]:
    """Each ``"A,B=VALUE"`` parsed, each pair of ``what`` once: a pair told twice is two
    answers to one question (A,B and B,A are one pair), refused naming both values."""
    pairs = [parse(value, source, f"{where}[{index}]" if where else "")
             for index, value in enumerate(values)]
    for index, pair in enumerate(pairs):
        for earlier in pairs[:index]:
            if {earlier.first, earlier.second} == {pair.first, pair.second}:
                raise InputError(f"{pair.first},{pair.second} a second time ({shown(earlier)}, "
                                 f"then {shown(pair)})", f"each pair of {what} once",
                                 source=source, where=f"{where}[{index}]" if where else None)
    return tuple(pairs)


UNKNOWN_PORT = "unknown"
"""What a port's coordinates say of a port nobody measured (``--port unknown``,
``--port front=unknown``): the calibration finds it from the data."""


def parse_named_port(value: str, source: str | Path, where: str
                     ) -> tuple[str | None, NDArray[np.float64]]:
    """``NAME=X,Y,Z`` (a named port) or ``X,Y,Z`` (the one port), mm, to (name, port in m)."""
    name, equals, coordinates = value.partition("=")
    if not equals:
        return None, parse_port_mm(value, source, where)
    if not name.strip():
        raise InputError(f"{value!r}", "NAME=X,Y,Z in mm, or X,Y,Z", source=source, where=where)
    return name.strip(), parse_port_mm(coordinates, source, where)


def parse_told_port(value: str, source: str | Path, where: str
                    ) -> tuple[str | None, NDArray[np.float64] | None]:
    """:func:`parse_named_port`, or :data:`UNKNOWN_PORT` for X,Y,Z: (name, None)."""
    name, equals, coordinates = value.rpartition("=")
    if coordinates.strip() == UNKNOWN_PORT and (not equals or name.strip()):
        return name.strip() or None, None
    return parse_named_port(value, source, where)


def _told_port(value: object, source: str | Path, where: str) -> NDArray[np.float64] | None:
    """A port of the capture file, m, or None for :data:`UNKNOWN_PORT`."""
    return None if value == UNKNOWN_PORT else parse_port_mm(value, source, where)


def _parse_rig(document: Table) -> Rig:
    """The rig of ``port_mm`` or ``[ports]``, and ``[rig]``."""
    ports = document.table("ports", expected="a table of name = [x, y, z] in mm")
    if document.has("port_mm") and ports.values:
        raise document.error("port_mm", "both port_mm and [ports]", "one of them")
    names = tuple(str(name) for name in ports.values)
    values = [_told_port(value, document.source or "", ports.where(name))
              for name, value in ports.values.items()]
    if document.has("port_mm"):
        names = ("port",)
        values = [_told_port(document.values["port_mm"], document.source or "",
                             document.where("port_mm"))]
    table = document.table("rig", allowed=_RIG_KEYS)
    attachment = parse_port_mm(table.values.get("attachment_mm", [0.0, 0.0, 0.0]),
                               document.source or "", table.where("attachment_mm"))
    distances = table.values.get("distances", [])
    if not isinstance(distances, list):
        raise table.error("distances", f"{distances!r}", 'a list of "A,B=MM"')
    angles = table.values.get("angles", [])
    if not isinstance(angles, list):
        raise table.error("angles", f"{angles!r}", 'a list of "A,B=DEG"')
    return Rig(np.reshape([np.zeros(3) if value is None else value for value in values],
                          (-1, 3)), names, attachment,
               unknown_ports=tuple(name for name, value in zip(names, values, strict=True)
                                   if value is None),
               distances=parse_distances(distances, document.source or "",
                                         table.where("distances")),
               angles=parse_angles(angles, document.source or "", table.where("angles")))


def write_capture(
    path: str | Path,
    *,
    robot: str,
    port_m: NDArray[np.float64] | None = None,
    measurements: str,
    truth: str | None = None,
    calibration: CalibrationSettings | None = None,
    encoder: dict[str, str | int | float] | None = None,
    rig: Rig | None = None,
) -> None:
    """Write a capture file atomically; ``robot``, ``measurements``, ``truth`` are relative.

    The rig is ``port_m`` alone, or ``rig``: one port named ``port`` is written as
    ``port_mm``, other ports as ``[ports]``; an attachment off the flange, known distances and
    known angles as ``[rig]``.
    """
    if rig is None:
        rig = Rig() if port_m is None else Rig.cable(port_m)
    lines = [
        "# Written by twin; `twin calibrate THIS_FILE` needs nothing else.",
        f"robot = {json.dumps(robot)}",
    ]
    if rig.port_names == ("port",):
        lines.append("port_mm = " + _vector_mm(rig.ports_m[0]))
    lines.append(f"measurements = {json.dumps(measurements)}")
    if truth is not None:
        lines.append(f"truth = {json.dumps(truth)}")
    if len(rig.ports_m) and rig.port_names != ("port",):
        lines.append("[ports]")
        lines += [f"{json.dumps(name)} = {_vector_mm(port)}"
                  for name, port in zip(rig.port_names, rig.ports_m, strict=True)]
    if np.any(np.abs(rig.attachment_m) > 0) or rig.distances or rig.angles:
        lines.append("[rig]")
        lines.append("attachment_mm = " + _vector_mm(rig.attachment_m))
        if rig.distances:
            lines.append("distances = [" + ", ".join(
                json.dumps(f"{d.first},{d.second}={float(m_to_mm(d.length_m))!r}")
                for d in rig.distances) + "]")
        if rig.angles:
            lines.append("angles = [" + ", ".join(
                json.dumps(f"{a.first},{a.second}={math.degrees(a.angle_rad)!r}")
                for a in rig.angles) + "]")
    if calibration is not None:
        lines += [*calibration_lines(calibration), f"cable_tension_n = {rig.tension_n!r}"]
    if encoder:
        lines.append("[encoder]")
        lines += [f"{key} = {json.dumps(value)}" for key, value in encoder.items()]
    write_atomic(path, "\n".join(lines) + "\n")


def _vector_mm(values_m: NDArray[np.float64]) -> str:
    return "[" + ", ".join(repr(float(v)) for v in m_to_mm(values_m)) + "]"
