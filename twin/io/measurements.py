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

from twin.dataset import Measurements
from twin.errors import InputError
from twin.io.atomic import write_atomic
from twin.io.paths import MAX_LINE_CHARS, read_text
from twin.robot import RobotModel
from twin.units import MAX_LENGTH_M, deg_to_rad, m_to_mm, mm_to_m, rad_to_deg

JOINT_COLUMNS = tuple(f"q{i}" for i in range(1, 7))
LENGTH_COLUMN = "length"
COLUMNS = (*JOINT_COLUMNS, LENGTH_COLUMN)


class UnitWarning(UserWarning):
    """Values that look like they are in the wrong unit."""


def read_table(
    path: str | Path, columns: tuple[str, ...], what: str, *, stdin: bool = False,
    journal: bool = False,
) -> tuple[NDArray[np.float64], list[int]]:
    """Read the named numeric columns of a CSV file.

    Blank lines and lines starting with ``#`` are skipped; other columns are ignored. Lines are
    at most :data:`~twin.io.paths.MAX_LINE_CHARS` long.

    Args:
        path: The file (``-``: standard input, if ``stdin``).
        columns: The columns to read.
        what: What the file should be, for messages.
        stdin: Whether ``-`` means standard input.
        journal: The command's own resumable file (see :func:`twin.io.paths.read_bytes`).

    Returns:
        ``(values, lines)``: values (rows, len(columns)) as written, and each row's line number.
    """
    text = read_text(path, what, stdin=stdin, journal=journal)
    for number, line in enumerate(io.StringIO(text), start=1):
        # Before the csv module, whose field limit would otherwise raise its own error.
        if len(line.rstrip("\r\n")) > MAX_LINE_CHARS:
            raise InputError(f"a line of {len(line.rstrip())} characters",
                             f"{what} with lines of at most {MAX_LINE_CHARS}", source=path,
                             where=f"line {number}")
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


def load_measurements(path: str | Path, robot: RobotModel | None = None, *,
                      stdin: bool = False) -> Measurements:
    """Read a measurement CSV (degrees, mm) into SI measurements.

    Args:
        path: The CSV file.
        robot: If given, every joint angle is checked against its limits.
        stdin: Whether the path ``-`` means standard input.

    Raises:
        InputError: on any problem with the file, naming line and column.
    """
    values, lines = read_table(path, COLUMNS, "a measurement CSV (q1..q6 in deg, length in mm)",
                               stdin=stdin)
    q_deg, length_mm = values[:, :6], values[:, 6]
    longest_mm = float(m_to_mm(MAX_LENGTH_M))
    bad = np.flatnonzero((length_mm <= 0) | (length_mm > longest_mm))
    if bad.size:
        raise InputError(f"{length_mm[bad[0]]:g} mm",
                         f"a positive cable length in mm, at most {longest_mm:g}",
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
    *,
    stdin: bool = False,
    journal: bool = False,
) -> tuple[NDArray[np.float64], list[int]]:
    """Read joint angles: CSV with columns q1..q6 in degrees (a measurement file without
    ``length``: a pose plan, or a robot program); other columns are ignored.

    Args:
        path: The CSV file.
        robot: If given, every joint angle is checked against its limits.
        what: What the file is, for error messages.
        stdin: Whether the path ``-`` means standard input.
        journal: The command's own file (see :func:`twin.io.paths.read_bytes`).

    Returns:
        ``(q_rad, lines)``: joint angles, shape (N, 6), rad, and each pose's line in the file.

    Raises:
        InputError: on any problem with the file, naming line and column.
    """
    q_deg, lines = read_table(path, JOINT_COLUMNS, what, stdin=stdin, journal=journal)
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
    q_deg, length_mm = rad_to_deg(measurements.q_rad), m_to_mm(measurements.lengths)
    lines = [",".join(COLUMNS)]
    lines += [
        ",".join(repr(float(v)) for v in (*q, length))
        for q, length in zip(q_deg, length_mm, strict=True)
    ]
    return "\n".join(lines) + "\n"


def write_measurements(path: str | Path, measurements: Measurements) -> None:
    """Write a measurement CSV atomically."""
    write_atomic(path, format_measurements(measurements))
