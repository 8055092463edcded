"""Measurement files: CSV with header ``q1,…,q6,length``, degrees and mm, one row per pose.

Other columns are ignored. Every problem is reported as one :class:`~twin.errors.InputError`
naming the file, the line and column, what was found and what was expected.
"""

from __future__ import annotations

import csv
import io
import math
import warnings
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from twin.cable import Measurements
from twin.errors import InputError
from twin.io.atomic import write_atomic
from twin.robot import RobotModel
from twin.units import deg_to_rad, m_to_mm, mm_to_m, rad_to_deg

JOINT_COLUMNS = tuple(f"q{i}" for i in range(1, 7))
LENGTH_COLUMN = "length"
COLUMNS = (*JOINT_COLUMNS, LENGTH_COLUMN)


class UnitWarning(UserWarning):
    """Values that look like they are in the wrong unit."""


def read_text(path: str | Path, what: str) -> str:
    """The UTF-8 text of a user file, or an InputError saying why it cannot be read."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise InputError("no such file", what, source=path) from None
    except IsADirectoryError:
        raise InputError("a directory", what, source=path) from None
    except OSError as exc:
        raise InputError(f"an unreadable file ({exc.strerror})", what, source=path) from None
    if b"\x00" in raw:
        raise InputError("binary data", what, source=path)
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"bytes that are not UTF-8 at offset {exc.start}", what,
                         source=path) from None


def read_table(
    path: str | Path, columns: tuple[str, ...], what: str
) -> tuple[NDArray[np.float64], list[int]]:
    """Read the named numeric columns of a CSV file.

    Blank lines and lines starting with ``#`` are skipped; other columns are ignored.

    Returns:
        ``(values, lines)``: values (rows, len(columns)) as written, and each row's line number.
    """
    text = read_text(path, what)
    expected_header = "a header " + ",".join(columns)
    rows = [
        (number, fields)
        for number, fields in enumerate(csv.reader(io.StringIO(text)), start=1)
        if fields and any(f.strip() for f in fields) and not fields[0].lstrip().startswith("#")
    ]
    if not rows:
        raise InputError("an empty file", f"{expected_header} and one row per pose", source=path)
    header_line, header = rows[0]
    header = [name.strip() for name in header]
    missing = [name for name in columns if name not in header]
    if missing:
        raise InputError(
            f"columns {','.join(header)} (no {','.join(missing)})", expected_header,
            source=path, where=f"line {header_line}",
        )
    duplicated = sorted({name for name in columns if header.count(name) > 1})
    if duplicated:
        raise InputError(f"column {duplicated[0]!r} twice", "each column once",
                         source=path, where=f"line {header_line}")
    if len(rows) == 1:
        raise InputError("a header and no data rows", "one row per pose", source=path)
    index = [header.index(name) for name in columns]
    values = np.empty((len(rows) - 1, len(columns)))
    lines = []
    for row, (number, fields) in enumerate(rows[1:]):
        if len(fields) != len(header):
            raise InputError(
                f"{len(fields)} fields", f"{len(header)}, one per header column",
                source=path, where=f"line {number}",
            )
        for col, (name, k) in enumerate(zip(columns, index, strict=True)):
            text_value = fields[k].strip()
            try:
                value = float(text_value)
            except ValueError:
                raise InputError(f"{text_value!r}", "a number", source=path,
                                 where=f"line {number}, column {name}") from None
            if not math.isfinite(value):
                raise InputError(f"{text_value!r}", "a finite number", source=path,
                                 where=f"line {number}, column {name}")
            values[row, col] = value
        lines.append(number)
    return values, lines


def load_measurements(path: str | Path, robot: RobotModel | None = None) -> Measurements:
    """Read a measurement CSV (degrees, mm) into SI measurements.

    Args:
        path: The CSV file.
        robot: If given, every joint angle is checked against its limits.

    Raises:
        InputError: on any problem with the file, naming line and column.
    """
    values, lines = read_table(path, COLUMNS, "a measurement CSV (q1..q6 in deg, length in mm)")
    q_deg, length_mm = values[:, :6], values[:, 6]
    bad = np.flatnonzero(length_mm <= 0)
    if bad.size:
        raise InputError(f"{length_mm[bad[0]]:g} mm", "a positive cable length in mm",
                         source=path, where=f"line {lines[bad[0]]}, column length")
    if robot is not None:
        check_joint_limits(q_deg, lines, robot, path)
    if len(lines) >= 3 and np.all(np.abs(q_deg) <= 2 * math.pi) and np.any(q_deg != 0):
        warnings.warn(
            f"{path}: every joint angle is within ±2π; the columns q1..q6 are read as degrees "
            "— convert them if they are radians",
            UnitWarning, stacklevel=2,
        )
    return Measurements(deg_to_rad(q_deg), mm_to_m(length_mm))


def load_plan(
    path: str | Path,
    robot: RobotModel | None = None,
    what: str = "a pose plan CSV (q1..q6 in degrees)",
) -> tuple[NDArray[np.float64], list[int]]:
    """Read joint angles: CSV with columns q1..q6 in degrees (a measurement file without
    ``length``: a pose plan, or a robot program); other columns are ignored.

    Args:
        path: The CSV file.
        robot: If given, every joint angle is checked against its limits.
        what: What the file is, for error messages.

    Returns:
        ``(q_rad, lines)``: joint angles, shape (N, 6), rad, and each pose's line in the file.

    Raises:
        InputError: on any problem with the file, naming line and column.
    """
    q_deg, lines = read_table(path, JOINT_COLUMNS, what)
    if robot is not None:
        check_joint_limits(q_deg, lines, robot, path)
    return deg_to_rad(q_deg), lines


def check_joint_limits(
    q_deg: NDArray[np.float64], lines: list[int], robot: RobotModel, path: str | Path
) -> None:
    """Raise an InputError for the first joint angle outside the robot's limits."""
    lower, upper = rad_to_deg(robot.lower_rad), rad_to_deg(robot.upper_rad)
    outside = (q_deg < lower - 1e-9) | (q_deg > upper + 1e-9)
    if np.any(outside):
        row, joint = np.argwhere(outside)[0]
        raise InputError(
            f"{q_deg[row, joint]:g} deg",
            f"within [{lower[joint]:g}, {upper[joint]:g}] deg (joint {joint + 1} of {robot.name})",
            source=path, where=f"line {lines[row]}, column q{joint + 1}",
        )


def format_measurements(measurements: Measurements) -> str:
    """The CSV text (header, degrees, mm) of measurements, exactly round-tripping floats."""
    q_deg, length_mm = rad_to_deg(measurements.q_rad), m_to_mm(measurements.length_m)
    lines = [",".join(COLUMNS)]
    lines += [
        ",".join(repr(float(v)) for v in (*q, length))
        for q, length in zip(q_deg, length_mm, strict=True)
    ]
    return "\n".join(lines) + "\n"


def write_measurements(path: str | Path, measurements: Measurements) -> None:
    """Write a measurement CSV atomically."""
    write_atomic(path, format_measurements(measurements))
