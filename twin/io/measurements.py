"""Measurement files: CSV, one row per pose, degrees and mm.

Columns ``q1..qN`` (the robot's joints: degrees, mm for a prismatic joint) and the columns of
exactly one measurement kind (:attr:`twin.kinds.base.Kind.columns` and its labels; the kind
reads, checks and writes them):

- ``length`` — a cable length (mm) from a drawstring encoder; with an optional ``port`` column
  naming the port each row's cable ran from, when the encoder was moved between ports;
- ``x,y,z`` — the measured point's position in the instrument's frame (mm), from a laser
  tracker;
- ``point`` — the name of the unknown fixed place the measured point was brought to (a ball in a
  socket, a pointer on a mark).

A kind whose columns hold another's (a pose's ``x,y,z`` and its orientation) is the one a file
with all of them holds.

Optional ``approach1..approachN`` (+1 / −1): the direction each joint last moved in before the
reading, which backlash depends on. Optional ``session``, beside any kind's columns: a label
(any text of 1 to 64 characters) naming the capture session of each row — cable lengths get an
encoder zero per session (:mod:`twin.kinds.length`), ``--cv-by session`` holds each out.
Optional per-row columns beside any kind's readings (:data:`twin.dataset.ROW_COLUMNS`):
``t_s`` (s since the capture started, >= 0), ``temperature_c`` (°C, within
:data:`twin.dataset.TEMPERATURE_RANGE_C`) and ``reference`` (1 on a reference pose revisited
during the capture, else 0), which the drift test reads.
Other columns are ignored; ``#`` lines are comments. Fields are separated by commas, or — as
a spreadsheet exports them where the decimal mark is a comma — by semicolons or tabs
(:func:`csv_rows`), whose numbers may then take a decimal comma. Every problem is reported as one
:class:`~twin.errors.InputError` naming the file, the line and column, what was found and what
was expected.
"""

from __future__ import annotations

import csv
import io
import math
import re
import warnings
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from twin.dataset import (
    REFERENCE,
    ROW_COLUMNS,
    TEMPERATURE,
    TEMPERATURE_RANGE_C,
    TIME,
    Labels,
    Measurements,
)
from twin.errors import InputError
from twin.io.atomic import write_atomic
from twin.io.paths import MAX_LINE_CHARS, read_text
from twin.io.table import shown
from twin.kinds import KINDS, Kind
from twin.rig import SESSION_LABELS
from twin.robot import RobotModel
from twin.units import joint_file_units, joints_from_file, joints_to_file


def joint_columns(n_joints: int) -> tuple[str, ...]:
    """``q1``…``qN``."""
    return tuple(f"q{i}" for i in range(1, n_joints + 1))


def joint_units_said(n_joints: int, robot: RobotModel | None = None) -> str:
    """How a file's joint columns are read, for messages: ``q1..q6 in deg``, or with prismatic
    joints ``q1..q8 in deg (q1 in mm)``."""
    columns = joint_columns(n_joints)
    said = f"{columns[0]}..{columns[-1]} in deg"
    if robot is None or not robot.prismatic.any():
        return said
    sliding = ",".join(name for name, slides in zip(columns, robot.prismatic, strict=True)
                       if slides)
    return f"{said} ({sliding} in mm)"


def approach_columns(n_joints: int) -> tuple[str, ...]:
    """``approach1``…``approachN``."""
    return tuple(f"approach{i}" for i in range(1, n_joints + 1))


JOINT_COLUMNS = joint_columns(6)
"""The joint columns of a 6-joint arm."""
MAX_LABEL_CHARS = 64
"""Longest port or point name."""


class UnitWarning(UserWarning):
    """Values that look like they are in the wrong unit."""


class Columns(NamedTuple):
    """What :func:`read_columns` read."""

    values: NDArray[np.float64]
    """The required numeric columns, as written, shape (rows, len(columns))."""
    optional: dict[str, NDArray[np.float64]]
    """Each optional numeric column the file has, shape (rows,)."""
    labels: dict[str, list[str]]
    """Each label (text) column the file has, one string per row."""
    lines: list[int]
    """Each row's line number in the file."""
    header: tuple[str, ...]
    """The file's columns, as named in its header."""
    header_line: int
    """The header's line number."""


def read_columns(
    path: str | Path, columns: tuple[str, ...], what: str, *,
    optional: tuple[str, ...] = (), labels: tuple[str, ...] = (), stdin: bool = False,
    journal: bool = False,
) -> Columns:
    """Read named columns of a CSV file: numbers required, numbers optional, text labels.

    Blank lines and lines starting with ``#`` are skipped; other columns are ignored. Lines are
    at most :data:`~twin.io.paths.MAX_LINE_CHARS` long.

    Args:
        path: The file (``-``: standard input, if ``stdin``).
        columns: Numeric columns every row must have.
        what: What the file should be, for messages.
        optional: Numeric columns read when the header has them.
        labels: Text columns read when the header has them (non-empty, at most
            :data:`MAX_LABEL_CHARS`).
        stdin: Whether ``-`` means standard input.
        journal: The command's own resumable file (see :func:`twin.io.paths.read_bytes`).
    """
    rows, comma = csv_rows(read_text(path, what, stdin=stdin, journal=journal), path, what)
    header = _header(rows, columns, (*optional, *labels), path)
    header_line = rows[0][0]
    numeric = (*columns, *(name for name in optional if name in header))
    named = tuple(name for name in labels if name in header)
    values = np.empty((len(rows) - 1, len(numeric)))
    texts: dict[str, list[str]] = {name: [] for name in named}
    lines = []
    for row, (number, fields) in enumerate(rows[1:]):
        if len(fields) != len(header):
            raise InputError(
                f"{len(fields)} fields", f"{len(header)}, one per header column",
                source=path, where=f"line {number}",
            )
        for col, name in enumerate(numeric):
            values[row, col] = _cell(fields[header.index(name)].strip(), comma, path,
                                     f"line {number}, column {name}")
        for name in named:
            label = fields[header.index(name)].strip()
            if not label or len(label) > MAX_LABEL_CHARS:
                raise InputError(shown(label), f"a name of 1 to {MAX_LABEL_CHARS} characters",
                                 source=path, where=f"line {number}, column {name}")
            texts[name].append(label)
        lines.append(number)
    count = len(columns)
    extra = {name: values[:, count + k] for k, name in enumerate(numeric[count:])}
    return Columns(values[:, :count], extra, texts, lines, tuple(header), header_line)


def csv_rows(text: str, path: str | Path, what: str
             ) -> tuple[list[tuple[int, list[str]]], bool]:
    """The CSV rows of ``text`` that are neither blank nor comments, with their line numbers
    (lines no longer than :data:`~twin.io.paths.MAX_LINE_CHARS`), and whether its numbers may
    take a decimal comma. The delimiter is read from the first such line: the one it names when
    it is Excel's ``sep=;`` (then skipped), else a semicolon or a tab where it has one (a
    spreadsheet's export where the decimal mark is a comma), else a comma."""
    for number, line in enumerate(io.StringIO(text), start=1):
        # Before the csv module, whose field limit would otherwise raise its own error.
        if len(line.rstrip("\r\n")) > MAX_LINE_CHARS:
            raise InputError(f"a line of {len(line.rstrip())} characters",
                             f"{what} with lines of at most {MAX_LINE_CHARS}", source=path,
                             where=f"line {number}")
    first = next((line.strip() for line in text.splitlines()
                  if line.strip() and not line.lstrip().startswith("#")), "")
    named = re.fullmatch(r"sep=(.)", first)
    delimiter = named.group(1) if named else next(
        (mark for mark in (";", "\t") if mark in first), ",")
    rows = [(number, fields) for number, fields
            in enumerate(csv.reader(io.StringIO(text), delimiter=delimiter), start=1)
            if fields and any(f.strip() for f in fields)
            and not fields[0].lstrip().startswith("#")]
    return rows[1:] if named else rows, delimiter != ","


def finite_number(text: str, decimal_comma: bool) -> float:
    """The finite number a CSV field holds; with ``decimal_comma``, one comma and no point is
    its decimal mark (``0,75``), and a field with both marks is not a number.

    Raises:
        ValueError: for anything else, with what was expected ("a number", "a finite number").
    """
    mark = " (a decimal comma or point)" if decimal_comma else ""
    if decimal_comma and text.count(",") == 1 and "." not in text:
        text = text.replace(",", ".")
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"a number{mark}") from None
    if not math.isfinite(value):
        raise ValueError("a finite number")
    return value


def _header(rows: list[tuple[int, list[str]]], columns: tuple[str, ...],
            others: tuple[str, ...], path: str | Path) -> list[str]:
    """The header's names (the first row): every required column, each column once, and at
    least one data row after it."""
    expected_header = "a header " + ",".join(columns)
    if not rows:
        raise InputError("an empty file", f"{expected_header} and one row per pose", source=path)
    header_line, header = rows[0][0], [name.strip() for name in rows[0][1]]
    missing = [name for name in columns if name not in header]
    if missing:
        # The line is not quoted: a file of another kind (`--joints /etc/passwd`) keeps its
        # content to itself.
        raise InputError(f"a header without {','.join(missing)}", expected_header,
                         source=path, where=f"line {header_line}")
    duplicated = sorted({name for name in (*columns, *others) if header.count(name) > 1})
    if duplicated:
        raise InputError(f"column {duplicated[0]!r} twice", "each column once",
                         source=path, where=f"line {header_line}")
    if len(rows) == 1:
        raise InputError("a header and no data rows", "one row per pose", source=path)
    return header


def _cell(text: str, decimal_comma: bool, path: str | Path, where: str) -> float:
    """A numeric cell: a finite number (:func:`finite_number`)."""
    try:
        return finite_number(text, decimal_comma)
    except ValueError as exc:
        raise InputError(shown(text), str(exc), source=path, where=where) from None


def read_table(
    path: str | Path, columns: tuple[str, ...], what: str, *, stdin: bool = False,
    journal: bool = False,
) -> tuple[NDArray[np.float64], list[int]]:
    """The named numeric columns of a CSV file (:func:`read_columns` without options).

    Returns:
        ``(values, lines)``: values (rows, len(columns)) as written, and each row's line number.
    """
    table = read_columns(path, columns, what, stdin=stdin, journal=journal)
    return table.values, table.lines


def _required(kind: Kind) -> set[str]:
    return {*kind.columns, *kind.labels}


def _which_kind(table: Columns, joints: tuple[str, ...], path: str | Path) -> Kind:
    """The one kind whose columns the file has (a kind whose columns another's hold gives way
    to it); a file with some of a kind's columns only, or with none or two kinds, is refused."""
    header = set(table.header)
    given = [kind for kind in KINDS.values() if _required(kind) <= header]
    given = [kind for kind in given
             if not any(_required(kind) < _required(other) for other in given)]
    partial = [kind for kind in KINDS.values()
               if 0 < len(_required(kind) & header) < len(_required(kind))
               and not (len(given) == 1 and _required(kind) & header <= _required(given[0]))]
    if len(given) != 1 or partial:
        texts = [kind.columns_text for kind in KINDS.values()]
        kinds = ", ".join(texts[:-1]) + f" or {texts[-1]}"
        known = {*joints, *(name for kind in KINDS.values()
                            for name in (*_required(kind), *kind.optional_labels))}
        raise InputError(f"columns {','.join(name for name in table.header if name in known)}",
                         f"exactly one of {kinds} beside {joints[0]}..{joints[-1]}",
                         source=path, where=f"line {table.header_line}")
    return given[0]


def _refuse_other_labels(table: Columns, kind: Kind, path: str | Path) -> None:
    """Refuse a label column another kind reads (a port beside tracker positions)."""
    for other in KINDS.values():
        for label in other.optional_labels:
            if other is not kind and label in table.labels:
                raise InputError(f"a {label} column", f"{label} only beside "
                                 f"{','.join(other.columns)}", source=path,
                                 where=f"line {table.header_line}")


def load_labels(path: str | Path, column: str) -> list[str]:
    """The text of one column of a measurement CSV, one label per data row (a placement, a
    session: what cross-validation groups the poses by).

    Raises:
        InputError: if the file has no such column, or a cell is empty.
    """
    table = read_columns(path, (), f"a measurement CSV with a column {column!r}",
                         labels=(column,))
    if column not in table.labels:
        raise InputError(f"no column {column!r} (columns {','.join(table.header)})",
                         "the label column to group the poses by", source=path,
                         where=f"line {table.header_line}")
    return table.labels[column]


def _prismatic(robot: RobotModel | None) -> NDArray[np.bool_] | None:
    """Which of the robot's joints slide (their q in mm in files), or None without a robot."""
    return None if robot is None else robot.prismatic


def load_measurements(path: str | Path, robot: RobotModel | None = None, *,
                      stdin: bool = False) -> Measurements:
    """Read a measurement CSV (degrees, mm) into SI measurements; see the module docstring.

    Args:
        path: The CSV file.
        robot: The robot measured: its joint count sets the ``q`` columns (6 without it), its
            prismatic joints' columns are read in mm, and every joint value is checked against
            its limits.
        stdin: Whether the path ``-`` means standard input.

    Raises:
        InputError: on any problem with the file, naming line and column.
    """
    n = robot.n_joints if robot is not None else 6
    joints = joint_columns(n)
    texts = [kind.columns_text for kind in KINDS.values()]
    what = (f"a measurement CSV ({joint_units_said(n, robot)} and "
            + ", ".join(texts[:-1]) + f" or {texts[-1]})")
    numeric = tuple(dict.fromkeys(name for kind in KINDS.values() for name in kind.columns))
    labels = tuple(dict.fromkeys([*(name for kind in KINDS.values()
                                    for name in (*kind.optional_labels, *kind.labels)),
                                  SESSION_LABELS]))
    table = read_columns(path, joints, what,
                         optional=(*numeric, *approach_columns(n), *ROW_COLUMNS),
                         labels=labels, stdin=stdin)
    _refuse_extra_joints(table, n, path)
    kind = _which_kind(table, joints, path)
    q_file = table.values
    if robot is not None:
        check_joint_limits(q_file, table.lines, robot, path)
    _warn_radians(q_file, robot, joints, path)
    q_rad = joints_from_file(q_file, _prismatic(robot))
    approach = _approach(table, n, path)
    _refuse_other_labels(table, kind, path)
    try:
        measurements = kind.from_columns(q_rad, table.optional, table.labels, table.lines,
                                         approach)
    except InputError as exc:
        raise exc.at(path) from None
    rows = _row_columns(table, path)
    named = dict(measurements.labels)
    if SESSION_LABELS in table.labels:
        named[SESSION_LABELS] = Labels.of(table.labels[SESSION_LABELS])
    if not rows and len(named) == len(measurements.labels):
        return measurements
    return Measurements(measurements.q_rad, measurements.kind, {**measurements.values, **rows},
                        named, measurements.approach)


def _row_columns(table: Columns, path: str | Path) -> dict[str, NDArray[np.float64]]:
    """The per-row columns the file has (:data:`twin.dataset.ROW_COLUMNS`), each checked: a
    time >= 0 s, a temperature within :data:`TEMPERATURE_RANGE_C`, a reference flag 0 or 1."""
    low, high = TEMPERATURE_RANGE_C
    checks = {
        TIME: (lambda v: v >= 0.0, "a time >= 0 s since the capture started"),
        TEMPERATURE: (lambda v: (v >= low) & (v <= high),
                      f"a temperature in °C within [{low:g}, {high:g}]"),
        REFERENCE: (lambda v: np.isin(v, (0.0, 1.0)),
                    "1 on a reference pose revisited during the capture, else 0"),
    }
    rows = {}
    for name, (valid, expected) in checks.items():
        if name not in table.optional:
            continue
        values = table.optional[name]
        bad = np.flatnonzero(~valid(values))
        if bad.size:
            raise InputError(f"{values[bad[0]]:g}", expected, source=path,
                             where=f"line {table.lines[bad[0]]}, column {name}")
        rows[name] = values
    return rows


RADIAN_SPAN_FRACTION = 0.05
"""A joint column in degrees that spans less than this fraction of the joint's range in
degrees, while every value would fit its limits read as radians, looks like radians."""
MIN_VARYING_DEG = 1e-6
"""A column whose values spread by less than this (deg) is a fixed joint: it says nothing of
its unit."""


def _warn_radians(q_file: NDArray[np.float64], robot: RobotModel | None,
                  joints: tuple[str, ...], path: str | Path) -> None:
    """Warn (:class:`UnitWarning`) naming the columns that look like radians read as degrees:
    of the revolute columns that vary, those spanning less than
    :data:`RADIAN_SPAN_FRACTION` of their joint's range in degrees with every value inside
    the joint's limits read as radians — when they are at least half of the varying columns
    (one narrow column is a joint the capture barely moved, half of them a unit). Per column,
    so that one joint wound past 2π, or a fixed joint, does not hide the others.

    Args:
        q_file: joint values as the file writes them, shape (N, n), deg (mm for a prismatic
            joint, never checked here).
        robot: the robot measured (its limits), or None (±360° for every joint).
    """
    if q_file.shape[0] < 3:
        return
    n = q_file.shape[1]
    if robot is None:
        lower_rad, upper_rad = np.full(n, -2 * math.pi), np.full(n, 2 * math.pi)
        turning = np.ones(n, dtype=bool)
    else:
        lower_rad, upper_rad, turning = robot.lower_rad, robot.upper_rad, ~robot.prismatic
    span = np.ptp(q_file, axis=0)
    varying = turning & (span > MIN_VARYING_DEG)
    range_deg = np.degrees(upper_rad - lower_rad)
    inside_as_rad = np.all((q_file >= lower_rad) & (q_file <= upper_rad), axis=0)
    narrow = varying & inside_as_rad & (span < RADIAN_SPAN_FRACTION * range_deg)
    if np.count_nonzero(narrow) and 2 * np.count_nonzero(narrow) >= np.count_nonzero(varying):
        names = ", ".join(name for name, flag in zip(joints, narrow, strict=True) if flag)
        warnings.warn(
            f"{path}: the columns {names} span less than "
            f"{RADIAN_SPAN_FRACTION:.0%} of their joints' ranges and fit the limits as "
            "radians; they are read as degrees — if they are radians, convert the file with "
            "`twin import --angle-unit rad`",
            UnitWarning, stacklevel=3,
        )


def _refuse_extra_joints(table: Columns, n: int, path: str | Path) -> None:
    """Refuse joint (or approach) columns beyond the robot's n joints: a file of another arm,
    or the wrong robot file, not something to ignore."""
    extra = [name for name in table.header
             if re.fullmatch(r"(q|approach)(\d+)", name) and int(re.sub(r"\D", "", name)) > n]
    if extra:
        raise InputError(f"the column {extra[0]} for a robot of {n} joints",
                         f"q1..q{n} (and approach1..approach{n}): the robot file's joints — "
                         "is --robot the arm that was measured?", source=path,
                         where=f"line {table.header_line}")


def _approach(table: Columns, n: int, path: str | Path) -> NDArray[np.int8] | None:
    """The approach columns as ±1 labels, all or none of them."""
    names = approach_columns(n)
    present = [name for name in names if name in table.optional]
    if not present:
        return None
    if len(present) != n:
        missing = [name for name in names if name not in table.optional]
        raise InputError(f"no {','.join(missing)}", f"all of {names[0]}..{names[-1]} or none",
                         source=path)
    values = np.stack([table.optional[name] for name in names], axis=1)
    bad = np.argwhere(~np.isin(values, (-1.0, 1.0)))
    if bad.size:
        row, joint = bad[0]
        raise InputError(f"{values[row, joint]:g}", "+1 or -1 (the direction the joint last "
                         "moved in)", source=path,
                         where=f"line {table.lines[row]}, column {names[joint]}")
    return values.astype(np.int8)


def load_plan(
    path: str | Path,
    robot: RobotModel | None = None,
    what: str | None = None,
    *,
    stdin: bool = False,
    journal: bool = False,
) -> tuple[NDArray[np.float64], list[int]]:
    """Read joint values: CSV with columns q1..q6 in degrees (a measurement file without
    ``length``: a pose plan, or a robot program); other columns are ignored.

    Args:
        path: The CSV file.
        robot: If given, its joints' columns q1..qN (a prismatic joint's in mm), each value
            checked against its limits.
        what: What the file is, for error messages (a pose plan CSV if None).
        stdin: Whether the path ``-`` means standard input.
        journal: The command's own file (see :func:`twin.io.paths.read_bytes`).

    Returns:
        ``(q_rad, lines)``: joint values, shape (N, n), rad (m for a prismatic joint), and each
        pose's line in the file.

    Raises:
        InputError: on any problem with the file, naming line and column.
    """
    columns = joint_columns(robot.n_joints) if robot is not None else JOINT_COLUMNS
    what = what or f"a pose plan CSV ({joint_units_said(len(columns), robot)})"
    q_file, lines = read_table(path, columns, what, stdin=stdin, journal=journal)
    if robot is not None:
        check_joint_limits(q_file, lines, robot, path)
    return joints_from_file(q_file, _prismatic(robot)), lines


def load_plan_reference(path: str | Path, robot: RobotModel, *, journal: bool = False
                        ) -> NDArray[np.bool_]:
    """The plan's ``reference`` column (1 on a revisit of the reference pose, `twin plan
    --reference-every`), shape (N,); all False when the plan has none.

    Raises:
        InputError: for a value other than 0 or 1, naming line and column.
    """
    table = read_columns(path, joint_columns(robot.n_joints),
                         f"a pose plan CSV ({joint_units_said(robot.n_joints, robot)})",
                         optional=(REFERENCE,), journal=journal)
    flags = _row_columns(table, path).get(REFERENCE)
    return np.zeros(len(table.lines), dtype=bool) if flags is None else flags > 0.5


class Poses(NamedTuple):
    """Joint angles to evaluate a model at, with the directions the joints came from."""

    q_rad: NDArray[np.float64]
    """Joint values, shape (N, n), rad (m for a prismatic joint)."""
    approach: NDArray[np.int8] | None
    """The ``approach1..approachN`` columns (±1), shape (N, n), or None when absent."""
    lines: list[int]
    """Each pose's line in the file."""
    temperature_c: NDArray[np.float64] | None = None
    """The ``temperature_c`` column (°C), shape (N,), or None when absent."""


def load_poses(path: str | Path, robot: RobotModel, what: str, *, stdin: bool = False
               ) -> Poses:
    """Read joint values (``q1..qN`` in degrees, mm for a prismatic joint, checked against the
    limits) and, when the file has them, the ``approach1..approachN`` and ``temperature_c``
    columns; other columns are ignored.

    Raises:
        InputError: on any problem with the file, naming line and column.
    """
    n = robot.n_joints
    table = read_columns(path, joint_columns(n), what,
                         optional=(*approach_columns(n), TEMPERATURE), stdin=stdin)
    check_joint_limits(table.values, table.lines, robot, path)
    return Poses(joints_from_file(table.values, robot.prismatic), _approach(table, n, path),
                 table.lines, _row_columns(table, path).get(TEMPERATURE))


def check_joint_limits(
    q_file: NDArray[np.float64], lines: list[int], robot: RobotModel, path: str | Path
) -> None:
    """Raise an InputError for the first joint value (as the file writes it: degrees, mm for a
    prismatic joint) outside the robot's limits."""
    lower = joints_to_file(robot.lower_rad, robot.prismatic)
    upper = joints_to_file(robot.upper_rad, robot.prismatic)
    outside = (q_file < lower - 1e-9) | (q_file > upper + 1e-9)
    if np.any(outside):
        row, joint = np.argwhere(outside)[0]
        unit = joint_file_units(robot.prismatic)[joint]
        raise InputError(
            f"{q_file[row, joint]:g} {unit}",
            f"within [{lower[joint]:g}, {upper[joint]:g}] {unit} (joint {joint + 1} of "
            f"{robot.name})", source=path, where=f"line {lines[row]}, column q{joint + 1}",
        )


def format_measurements(measurements: Measurements, robot: RobotModel | None = None) -> str:
    """The CSV text (header, degrees, mm) of measurements of ``robot`` (whose prismatic joints'
    values are written in mm; every joint revolute without one), exactly round-tripping
    floats: the joints, the kind's columns (:meth:`twin.kinds.base.Kind.to_columns`), the
    approach."""
    n = measurements.q_rad.shape[1]
    header = list(joint_columns(n))
    columns: list[list[str]] = [[repr(float(v)) for v in row] for row in
                                joints_to_file(measurements.q_rad, _prismatic(robot))]
    readings = KINDS.lookup(measurements.kind).to_columns(measurements)
    header += [name for name, _ in readings]
    extra = [cells for _, cells in readings]
    if SESSION_LABELS in measurements.labels:
        header.append(SESSION_LABELS)
        extra.append(measurements.labels[SESSION_LABELS].per_row("session"))
    for name in ROW_COLUMNS:
        if name in measurements.values:
            header.append(name)
            extra.append([str(int(v)) if name == REFERENCE else repr(float(v))
                          for v in measurements.values[name]])
    if measurements.approach is not None:
        header += list(approach_columns(n))
        extra += [[f"{int(v):+d}" for v in measurements.approach[:, k]] for k in range(n)]
    lines = [",".join(header)]
    lines += [",".join([*row, *(column[i] for column in extra)])
              for i, row in enumerate(columns)]
    return "\n".join(lines) + "\n"


def write_measurements(path: str | Path, measurements: Measurements,
                       robot: RobotModel | None = None) -> None:
    """Write a measurement CSV of ``robot`` (:func:`format_measurements`) atomically."""
    write_atomic(path, format_measurements(measurements, robot))
