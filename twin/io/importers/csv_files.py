"""The CSV files people have into measurements: radians or degrees, metres or millimetres as
told (a prismatic joint's values in the length unit), joint columns named as the robot's joints
(a URDF's, or ``q1..qN``), headerless files, one file per fixed point.

- **With a header**: the joint columns are the robot's joint names (``panda_joint1``…) or
  ``q1..qN``; the reading is a measurement kind's columns (:attr:`twin.kinds.base.Kind.columns`:
  a ``length`` column, ``x,y,z`` columns…) or its label column (a ``point`` column: the name of
  the fixed place); without any, the file is one fixed point (the first kind that reads a label
  alone). Other columns are ignored.
- **Headerless** (``headerless``): each row is the n joints, then nothing (the file is one fixed
  point), a length, or x, y, z — the same count on every row (the kind with as many columns).
- A file that is a fixed point is named by its path below the inputs' common folder, without
  its suffix (``front/hole_0``), or by its stem when it is the only file.
- With ``session_by`` every row gets a ``session`` label (:data:`twin.rig.SESSION_LABELS`): its
  file's folder below the common folder (``folder``: ``front``, a fixture placement, a day's
  recordings) or the file itself (``file``: ``front/hole_0``), for ``--cv-by session`` and,
  with cable lengths, one encoder zero per session.

Fields are separated by commas, or — as a spreadsheet writes them where the decimal mark is a
comma — by semicolons, or by tabs (:func:`twin.io.measurements.csv_rows`); in a file of
semicolons or tabs a number may take a decimal comma (``0,75``).

A row that is not numbers, has the wrong number of fields, lies outside the joint limits, or has
a reading its kind refuses is left out and reported with the reason.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from twin.choices import ANGLE_UNITS, LENGTH_UNITS, SESSION_BY
from twin.dataset import Labels
from twin.errors import InputError, UnknownChoiceError
from twin.io.importers.base import Imported, outside_limits
from twin.io.measurements import csv_rows, finite_number, joint_columns
from twin.io.paths import read_text
from twin.kinds import KINDS, Kind
from twin.rig import SESSION_LABELS
from twin.robot import RobotModel
from twin.units import LENGTH_FACTORS, deg_to_rad, mm_to_m

WHAT = "a CSV of joint angles and readings"


def _rows(path: Path) -> tuple[list[tuple[int, list[str]]], bool]:
    """Numbered non-blank, non-comment rows of a CSV file, fields stripped, and whether its
    numbers may take a decimal comma (:func:`twin.io.measurements.csv_rows`)."""
    rows, comma = csv_rows(read_text(path, WHAT), path, WHAT)
    return [(number, [f.strip() for f in fields]) for number, fields in rows], comma


def _labelled() -> Kind:
    """The kind of a file without reading columns: the first that reads a label alone (the
    file is one fixed point)."""
    return next(kind for kind in KINDS.values() if not kind.columns and kind.labels)


def _layout(header: list[str], robot: RobotModel, path: Path, line: int
            ) -> tuple[list[int], Kind, list[int], int | None]:
    """Column indices of the joints, the kind, the indices of its numeric columns and of its
    label."""
    for names in (list(robot.joint_names), list(joint_columns(robot.n_joints))):
        if all(name in header for name in names):
            joints = [header.index(name) for name in names]
            break
    else:
        raise InputError(f"columns {','.join(header)}", "the robot's joints as columns: "
                         f"{','.join(robot.joint_names)} or "
                         f"{','.join(joint_columns(robot.n_joints))}", source=path,
                         where=f"line {line}")
    numeric = sorted((kind for kind in KINDS.values()
                      if kind.columns and all(c in header for c in kind.columns)),
                     key=lambda kind: -len(kind.columns))
    if numeric:
        return joints, numeric[0], [header.index(c) for c in numeric[0].columns], None
    for kind in KINDS.values():
        if not kind.columns and kind.labels and kind.labels[0] in header:
            return joints, kind, [], header.index(kind.labels[0])
    return joints, _labelled(), [], None


def point_names(paths: Sequence[Path]) -> list[str]:
    """The fixed point each file is: its path below the common folder, without suffix."""
    if len(paths) == 1:
        return [paths[0].stem]
    common = Path(os.path.commonpath([p.resolve().parent for p in paths]))
    return [p.resolve().relative_to(common).with_suffix("").as_posix() for p in paths]


def session_names(paths: Sequence[Path], by: str) -> list[str]:
    """Each file's session: its folder below the common folder (``.`` for a file there) or its
    path below it without suffix (:func:`point_names`)."""
    names = point_names(paths)
    if by == "file":
        return names
    return [name.rpartition("/")[0] or "." for name in names]


class _File:
    """The rows of one file kept, as q (rad), readings (the kind's file units) and labels."""

    def __init__(self, kind: Kind) -> None:
        self.kind = kind
        self.q: list[NDArray[np.float64]] = []
        self.values: list[list[float]] = []
        self.labels: list[str] = []
        self.lines: list[int] = []


def _headerless(rows: list[tuple[int, list[str]]], n: int, path: Path) -> Kind:
    """The kind of headerless rows: the one with as many columns as the fields after the
    joints."""
    width = len(rows[0][1]) - n
    found = [kind for kind in KINDS.values() if len(kind.columns) == width
             and (kind.columns or kind.labels)]
    if not found:
        texts = ", ".join(",".join(kind.columns) for kind in KINDS.values() if kind.columns)
        raise InputError(f"{len(rows[0][1])} fields on line {rows[0][0]}", f"{n} joints, "
                         f"then nothing or one of {texts}", source=path)
    return found[0]


def _refused(kind: Kind, q: NDArray[np.float64], values: list[float], line: int) -> str:
    """Why the kind refuses a row's reading, or ""."""
    try:
        kind.from_columns(q[None], {c: np.array([v]) for c, v in zip(kind.columns, values,
                                                                   strict=True)},
                          {label: ["row"] for label in kind.labels}, [line], None)
    except InputError as exc:
        return f"{exc.found}, expected {exc.expected}"
    return ""


def _read_file(path: Path, robot: RobotModel, headerless: bool, angle_unit: str,
               to_mm: float, name: str, dropped: list[str]) -> _File:
    """A file's kept rows, readings in mm."""
    rows, comma = _rows(path)
    if not rows:
        raise InputError("an empty file", "rows of joint angles", source=path)
    n = robot.n_joints
    if headerless:
        kind = _headerless(rows, n, path)
        joints, reading, label = list(range(n)), list(range(n, n + len(kind.columns))), None
    else:
        joints, kind, reading, label = _layout(rows[0][1], robot, path, rows[0][0])
        rows = rows[1:]
    kept = _File(kind)
    fields_expected = None if not headerless else n + len(reading)
    for line, fields in rows:
        where = f"{path}: line {line}"
        if fields_expected is not None and len(fields) != fields_expected:
            dropped.append(f"{where}: {len(fields)} fields, expected {fields_expected}: dropped")
            continue
        try:
            q = np.array([finite_number(fields[j], comma) for j in joints])
            values = [finite_number(fields[j], comma) * (1.0 if column in kind.unitless else to_mm)
                      for j, column in zip(reading, kind.columns, strict=True)]
        except (ValueError, IndexError):
            dropped.append(f"{where}: a field that is not a finite number: dropped")
            continue
        if angle_unit == "deg":
            q = np.where(robot.prismatic, q, deg_to_rad(q))
        q = np.where(robot.prismatic, mm_to_m(q * to_mm), q)
        reason = outside_limits(q, robot) or _refused(kind, q, values, line)
        if reason:
            dropped.append(f"{where}: {reason}: dropped")
            continue
        kept.q.append(q)
        kept.values.append(values)
        kept.labels.append(fields[label] if label is not None else name)
        kept.lines.append(line)
    return kept


def read_csv_files(paths: Sequence[str | Path], robot: RobotModel, *, angle_unit: str,
                   length_unit: str = "mm", headerless: bool = False,
                   session_by: str | None = None) -> Imported:
    """The poses of CSV files (see the module docstring); with ``session_by``
    (:data:`twin.choices.SESSION_BY`) each row labelled with its session.

    Raises:
        InputError: for an unknown unit, a header without the robot's joints, files of
            different kinds of reading, or no row kept.
    """
    if session_by is not None and session_by not in SESSION_BY:
        raise UnknownChoiceError("session", session_by, SESSION_BY, source="--session-by")
    if angle_unit not in ANGLE_UNITS:
        raise UnknownChoiceError("angle unit", angle_unit, ANGLE_UNITS, source="--angle-unit")
    if length_unit not in LENGTH_UNITS:
        raise UnknownChoiceError("length unit", length_unit, LENGTH_UNITS,
                                 source="--length-unit")
    files = [Path(p) for p in paths]
    dropped: list[str] = []
    parts = [_read_file(path, robot, headerless, angle_unit,
                        LENGTH_FACTORS[length_unit] / LENGTH_FACTORS["mm"], name, dropped)
             for path, name in zip(files, point_names(files), strict=True)]
    kinds = {part.kind.name for part in parts}
    if len(kinds) != 1:
        raise InputError("files with different readings (" + ", ".join(
            kind.what for kind in KINDS.values()) + ")", "one kind of reading in every file",
                         source=", ".join(map(str, files)))
    kind = parts[0].kind
    q = [row for part in parts for row in part.q]
    if not q:
        raise InputError("no row kept", "at least one row of joint angles within the limits",
                         source=", ".join(map(str, files)))
    values = np.array([v for part in parts for v in part.values],
                      dtype=np.float64).reshape(len(q), -1)
    labels = [label for part in parts for label in part.labels]
    measurements = kind.from_columns(
        np.array(q), {column: values[:, k] for k, column in enumerate(kind.columns)},
        {name: labels for name in kind.labels}, [line for part in parts for line in part.lines],
        None)
    if session_by is None:
        return Imported(measurements, dropped)
    sessions = [name for part, name in zip(parts, session_names(files, session_by),
                                           strict=True) for _ in part.q]
    return Imported(replace(measurements, labels={**measurements.labels,
                                                  SESSION_LABELS: Labels.of(sessions)}),
                    dropped)
