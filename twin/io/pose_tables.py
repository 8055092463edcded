"""CSV tables of joint values twin writes, and the Cartesian targets it reads (degrees, mm):

- a pose **plan** (`twin plan`): ``q1..qN`` (and ``port``, the station of each pose;
  ``reference``, 1 on the revisits of the first pose ``--reference-every`` asks for);
- **corrected** commands (`twin compensate`): ``q1..qN`` (empty when unreachable), ``status``,
  ``error_mm`` (the remaining flange error) and, with backlash, ``approach1..N``;
- **predictions** (`twin predict`): the poses as given, then ``x,y,z`` (mm, base frame) and
  the columns of the kind's readings: ``length`` (a cable from one port),
  ``tracker_x,tracker_y,tracker_z`` (a tracker, in its frame)…;
- **targets** (`twin compensate --targets`): ``x,y,z`` in mm (the flange centre in the base
  frame, or with an orientation the TCP in the work object), and optionally the orientation as
  a quaternion ``qw,qx,qy,qz`` (ABB's order, scalar first) or as fixed-axis angles ``rx,ry,rz``
  in degrees (R = Rz(rz)·Ry(ry)·Rx(rx), the URDF's roll–pitch–yaw and RobotStudio's Euler ZYX;
  not UR's rotation vector), and the configuration ``cf1,cf4,cf6,cfx``
  (:mod:`twin.compensation.configuration`).

Joint values are written in degrees, a prismatic joint's in mm (:mod:`twin.units`), to 1e-6 of
their unit; lengths to 1e-6 mm; every file atomically.
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from twin.arrays import Array
from twin.calibration.predict import Prediction
from twin.compensation.ik import STATUS_UNREACHABLE
from twin.compensation.joints import InOrder
from twin.dataset import REFERENCE
from twin.errors import InputError
from twin.io.atomic import write_atomic
from twin.io.measurements import approach_columns, joint_columns
from twin.kinds import KINDS
from twin.kinds.length import PORT
from twin.robot import RobotModel
from twin.units import (
    FILE_JOINT_DECIMALS,
    MAX_LENGTH_M,
    RESULT_MM_DECIMALS,
    joints_to_file,
    m_to_mm,
    mm_to_m,
    rounded,
)

TARGET_COLUMNS = ("x", "y", "z")
QUATERNION_COLUMNS = ("qw", "qx", "qy", "qz")
ANGLE_COLUMNS = ("rx", "ry", "rz")
CONFIGURATION_COLUMNS = ("cf1", "cf4", "cf6", "cfx")
INTEGER_TOLERANCE = 1e-9
"""How far from a whole number a configuration value may be written."""
RESULT_COLUMNS = ("status", "error_mm")
POSITION_COLUMNS = ("x", "y", "z")


def _joint_values(q_rad: Array, robot: RobotModel) -> list[list[str]]:
    """Each row's joint values as files write them (degrees, mm for a prismatic joint), to
    1e-6 of their unit."""
    return [list(map(repr, rounded(q, FILE_JOINT_DECIMALS)))
            for q in joints_to_file(q_rad, robot.prismatic)]


class PoseTargets(NamedTuple):
    """Targets read from a CSV (:func:`load_pose_targets`)."""

    position_m: Array
    """Shape (m, 3), m."""
    rotation: Array | None
    """Orientations, shape (m, 3, 3), or None for positions only."""
    configuration: NDArray[np.int64] | None
    """cf1, cf4, cf6, cfx per row, shape (m, 4), or None."""


def _column_set(found: dict[str, NDArray[np.float64]], names: tuple[str, ...], path: str | Path
                ) -> NDArray[np.float64] | None:
    given = [name for name in names if name in found]
    if not given:
        return None
    if len(given) != len(names):
        raise InputError(f"columns {','.join(given)}", f"all of {','.join(names)} or none",
                         source=path)
    return np.column_stack([found[name] for name in names])


def load_pose_targets(path: str | Path, *, stdin: bool = False) -> PoseTargets:
    """Targets x,y,z (mm) with an optional orientation and configuration (see the module
    docstring), in SI.

    Raises:
        InputError: naming the line of a target farther than any arm reaches, a quaternion that
            is not a unit one, a configuration that is not integers, or both orientations.
    """
    from twin.compensation.poses import QUATERNION_TOLERANCE, pose_matrices
    from twin.geometry.rigid import rotation as euler_rotation
    from twin.io.measurements import read_columns

    what = ("a target CSV (x,y,z in mm; optional qw,qx,qy,qz or rx,ry,rz in degrees; optional "
            "cf1,cf4,cf6,cfx)")
    table = read_columns(path, TARGET_COLUMNS, what, stdin=stdin,
                         optional=(*QUATERNION_COLUMNS, *ANGLE_COLUMNS, *CONFIGURATION_COLUMNS))
    far = np.flatnonzero(np.linalg.norm(table.values, axis=1) > m_to_mm(MAX_LENGTH_M))
    if far.size:
        raise InputError(f"a target {np.linalg.norm(table.values[far[0]]):g} mm away",
                         f"targets within {float(m_to_mm(MAX_LENGTH_M)):g} mm",
                         source=path, where=f"line {table.lines[far[0]]}")
    quaternion = _column_set(table.optional, QUATERNION_COLUMNS, path)
    angles = _column_set(table.optional, ANGLE_COLUMNS, path)
    conf = _column_set(table.optional, CONFIGURATION_COLUMNS, path)
    if quaternion is not None and angles is not None:
        raise InputError("both qw,qx,qy,qz and rx,ry,rz", "one orientation per row", source=path)
    rotation = None
    if quaternion is not None:
        off = np.abs(np.linalg.norm(quaternion, axis=1) - 1.0) > QUATERNION_TOLERANCE
        if np.any(off):
            row = int(np.argmax(off))
            raise InputError(f"a quaternion of norm {np.linalg.norm(quaternion[row]):.6g}",
                             f"a unit quaternion (within {QUATERNION_TOLERANCE:g})", source=path,
                             where=f"line {table.lines[row]}")
        rotation = pose_matrices(np.zeros((len(quaternion), 3)), quaternion)[:, :3, :3]
    elif angles is not None:
        rotation = euler_rotation(np.deg2rad(angles))
    if conf is not None and np.any(np.abs(conf - np.round(conf)) > INTEGER_TOLERANCE):
        row = int(np.argmax(np.any(np.abs(conf - np.round(conf)) > INTEGER_TOLERANCE, axis=1)))
        raise InputError(f"configuration {conf[row].tolist()}", "integers cf1,cf4,cf6,cfx",
                         source=path, where=f"line {table.lines[row]}")
    return PoseTargets(mm_to_m(table.values), rotation,
                       None if conf is None else np.round(conf).astype(np.int64))


def write_plan(path: str | Path, q_rad: Array, robot: RobotModel,
               port_names: tuple[str, ...] = (), port: NDArray[np.intp] | None = None,
               reference: NDArray[np.bool_] | None = None) -> None:
    """A pose plan of ``robot``: q1..qN (deg; mm for a prismatic joint), for an encoder
    moved between stations each pose's station (``port``: index into ``port_names``), and
    with revisits of a reference pose the ``reference`` flag (shape (N,); 1 on its rows)."""
    header = joint_columns(q_rad.shape[1]) + ((PORT,) if port is not None else ()) \
        + ((REFERENCE,) if reference is not None else ())
    rows = [",".join(header)]
    rows += [",".join([*values, *(() if port is None else (port_names[port[k]],)),
                       *(() if reference is None else (str(int(reference[k])),))])
             for k, values in enumerate(_joint_values(q_rad, robot))]
    write_atomic(path, "\n".join(rows) + "\n")


def format_corrected(ordered: InOrder, robot: RobotModel) -> str:
    """CSV text: ``robot``'s q1..qN (deg, mm for a prismatic joint, to 1e-6; empty when
    unreachable), status, remaining flange error (mm); with backlash, approach1..N: the side
    each joint must come from (the corrections hold for it)."""
    solved = ordered.solved
    error_mm = m_to_mm(solved.position_error_m)
    n = solved.q_rad.shape[1]
    header = [*joint_columns(n), *RESULT_COLUMNS,
              *(approach_columns(n) if ordered.approach is not None else ())]
    lines = [",".join(header)]
    for row, (values, status, error) in enumerate(zip(_joint_values(solved.q_rad, robot),
                                                      solved.status, error_mm, strict=True)):
        values = [""] * n if status == STATUS_UNREACHABLE else values
        sides = [] if ordered.approach is None else [f"{int(s):+d}"
                                                     for s in ordered.approach[row]]
        lines.append(",".join([*values, str(status), f"{error:.6f}", *sides]))
    return "\n".join(lines) + "\n"


def write_corrected(path: str | Path, ordered: InOrder, robot: RobotModel) -> None:
    """Write :func:`format_corrected` atomically."""
    write_atomic(path, format_corrected(ordered, robot))


def format_prediction(q_rad: Array, approach: NDArray[np.int8] | None,
                      prediction: Prediction, robot: RobotModel) -> str:
    """CSV text: the poses as given (``robot``'s q in degrees, mm for a prismatic joint;
    approach), then x,y,z and the columns of the kind's readings (length;
    tracker_x,tracker_y,tracker_z…: :meth:`twin.kinds.base.Kind.prediction_columns`) in mm to
    1e-6 mm."""
    n = q_rad.shape[1]
    readings = KINDS.lookup(prediction.kind).prediction_columns(prediction.readings)
    header = [*joint_columns(n), *(approach_columns(n) if approach is not None else ()),
              *POSITION_COLUMNS, *(name for name, _ in readings)]
    columns = _joint_values(q_rad, robot)
    if approach is not None:
        columns = [[*row, *(f"{int(v):+d}" for v in signs)]
                   for row, signs in zip(columns, approach, strict=True)]
    xyz = m_to_mm(prediction.position_m)
    lines = [",".join(header)]
    for i, row in enumerate(columns):
        values = rounded(xyz[i], RESULT_MM_DECIMALS) + rounded(
            [float(column[i]) for _, column in readings], RESULT_MM_DECIMALS)
        lines.append(",".join([*row, *map(repr, values)]))
    return "\n".join(lines) + "\n"


def write_prediction(path: str | Path, q_rad: Array, approach: NDArray[np.int8] | None,
                     prediction: Prediction, robot: RobotModel) -> None:
    """Write :func:`format_prediction` atomically."""
    write_atomic(path, format_prediction(q_rad, approach, prediction, robot))
