"""The CSV files people have into measurements: radians or degrees, metres or millimetres as
told (a prismatic joint's values in the length unit), joint columns named as the robot's joints
(a URDF's, or ``q1..qN``), headerless files, one file per fixed point.

- **With a header**: the joint columns are the robot's joint names (``panda_joint1``…) or
  ``q1..qN``; the reading is a ``length`` column, ``x,y,z`` columns or a ``point`` column (the
  name of the fixed place); without any, the file is one fixed point. Other columns are ignored.
- **Headerless** (``headerless``): each row is the n joints, then nothing (the file is one fixed
  point), a length, or x, y, z — the same count on every row.
- A file that is a fixed point is named by its path below the inputs' common folder, without
  its suffix (``front/hole_0``), or by its stem when it is the only file.

A row that is not numbers, has the wrong number of fields, or lies outside the joint limits is
left out and reported with the reason.
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from twin.choices import ANGLE_UNITS, LENGTH_UNITS
from twin.dataset import Measurements
from twin.errors import InputError, UnknownChoiceError
from twin.io.importers.base import Imported, outside_limits
from twin.io.measurements import LENGTH_COLUMN, POINT_COLUMN, POSITION_COLUMNS, joint_columns
from twin.io.paths import read_text
from twin.robot import RobotModel
from twin.units import LENGTH_FACTORS, MAX_LENGTH_M, deg_to_rad

WHAT = "a CSV of joint angles and readings"


def _rows(path: Path) -> list[tuple[int, list[str]]]:
    """Numbered non-blank, non-comment rows of a CSV file."""
    text = read_text(path, WHAT)
    return [(number, [f.strip() for f in fields])
            for number, fields in enumerate(csv.reader(io.StringIO(text)), start=1)
            if fields and any(f.strip() for f in fields) and not fields[0].lstrip().startswith("#")]


def _layout(header: list[str], robot: RobotModel, path: Path, line: int
            ) -> tuple[list[int], list[int], int | None]:
    """Column indices of the joints and the numeric reading, and of the point label."""
    for names in (list(robot.joint_names), list(joint_columns(robot.n_joints))):
        if all(name in header for name in names):
            joints = [header.index(name) for name in names]
            break
    else:
        raise InputError(f"columns {','.join(header)}", "the robot's joints as columns: "
                         f"{','.join(robot.joint_names)} or "
                         f"{','.join(joint_columns(robot.n_joints))}", source=path,
                         where=f"line {line}")
    if LENGTH_COLUMN in header:
        return joints, [header.index(LENGTH_COLUMN)], None
    if all(c in header for c in POSITION_COLUMNS):
        return joints, [header.index(c) for c in POSITION_COLUMNS], None
    return joints, [], header.index(POINT_COLUMN) if POINT_COLUMN in header else None


def point_names(paths: Sequence[Path]) -> list[str]:
    """The fixed point each file is: its path below the common folder, without suffix."""
    if len(paths) == 1:
        return [paths[0].stem]
    common = Path(os.path.commonpath([p.resolve().parent for p in paths]))
    return [p.resolve().relative_to(common).with_suffix("").as_posix() for p in paths]


def _number(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(text)
    return value


class _File:
    """The rows of one file kept, as q (rad), readings (m) and point labels."""

    def __init__(self) -> None:
        self.q: list[NDArray[np.float64]] = []
        self.values: list[list[float]] = []
        self.labels: list[str] = []


def _read_file(path: Path, robot: RobotModel, headerless: bool, angle_unit: str,
               length_factor: float, name: str, dropped: list[str]) -> tuple[_File, int]:
    """A file's kept rows and its reading's width (0: a fixed point)."""
    rows = _rows(path)
    if not rows:
        raise InputError("an empty file", "rows of joint angles", source=path)
    n = robot.n_joints
    if headerless:
        width = len(rows[0][1]) - n
        joints, reading, label = list(range(n)), list(range(n, n + max(width, 0))), None
        if width not in (0, 1, 3):
            raise InputError(f"{len(rows[0][1])} fields on line {rows[0][0]}", f"{n} joints, "
                             f"then nothing, a length or x,y,z", source=path)
    else:
        joints, reading, label = _layout(rows[0][1], robot, path, rows[0][0])
        rows = rows[1:]
    kept = _File()
    fields_expected = None if not headerless else n + len(reading)
    for line, fields in rows:
        where = f"{path}: line {line}"
        if fields_expected is not None and len(fields) != fields_expected:
            dropped.append(f"{where}: {len(fields)} fields, expected {fields_expected}: dropped")
            continue
        try:
            q = np.array([_number(fields[j]) for j in joints])
            values = [_number(fields[j]) * length_factor for j in reading]
        except (ValueError, IndexError):
            dropped.append(f"{where}: a field that is not a finite number: dropped")
            continue
        if angle_unit == "deg":
            q = np.where(robot.prismatic, q, deg_to_rad(q))
        q = np.where(robot.prismatic, q * length_factor, q)
        reason = outside_limits(q, robot) or (
            f"a length that is not in (0, {MAX_LENGTH_M:g}] m" if len(values) == 1
            and not 0 < values[0] <= MAX_LENGTH_M else "")
        if reason:
            dropped.append(f"{where}: {reason}: dropped")
            continue
        kept.q.append(q)
        kept.values.append(values)
        kept.labels.append(fields[label] if label is not None else name)
    return kept, len(reading) if label is None else -1


def read_csv_files(paths: Sequence[str | Path], robot: RobotModel, *, angle_unit: str,
                   length_unit: str = "mm", headerless: bool = False) -> Imported:
    """The poses of CSV files (see the module docstring).

    Raises:
        InputError: for an unknown unit, a header without the robot's joints, files of
            different kinds of reading, or no row kept.
    """
    if angle_unit not in ANGLE_UNITS:
        raise UnknownChoiceError("angle unit", angle_unit, ANGLE_UNITS, source="--angle-unit")
    if length_unit not in LENGTH_UNITS:
        raise UnknownChoiceError("length unit", length_unit, LENGTH_UNITS,
                                 source="--length-unit")
    files = [Path(p) for p in paths]
    dropped: list[str] = []
    parts = [_read_file(path, robot, headerless, angle_unit, LENGTH_FACTORS[length_unit], name,
                        dropped) for path, name in zip(files, point_names(files), strict=True)]
    widths = {width for _, width in parts}
    if len(widths) != 1:
        raise InputError("files with different readings (lengths, points, fixed points)",
                         "one kind of reading in every file", source=", ".join(map(str, files)))
    width = widths.pop()
    q = [row for part, _ in parts for row in part.q]
    if not q:
        raise InputError("no row kept", "at least one row of joint angles within the limits",
                         source=", ".join(map(str, files)))
    values = np.array([v for part, _ in parts for v in part.values], dtype=np.float64)
    if width == 1:
        return Imported(Measurements(np.array(q), values[:, 0]), dropped)
    if width == 3:
        return Imported(Measurements(np.array(q), position_m=values), dropped)
    labels = [label for part, _ in parts for label in part.labels]
    names = tuple(dict.fromkeys(labels))
    return Imported(Measurements(np.array(q), point=np.array([names.index(x) for x in labels]),
                                 point_names=names), dropped)
