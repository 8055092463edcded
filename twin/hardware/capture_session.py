"""Durable capture: measure the plan pose by pose, each row on disk before the next move.

Files in the output folder ``DIR``:

- ``plan.csv`` — a copy of the plan; a resumed capture must bring the same plan.
- ``measurements.csv`` — header ``pose,q1,…,qN,length,t_s,reference,approach1,…,approachN``
  (deg — mm for a prismatic joint —, mm, s, 0/1, ±1; N the robot's joints, 4 to 9),
  one row per measured pose, appended as one whole line and ``fsync``-ed before the robot moves
  on (a journal, :mod:`twin.io.journal`). ``pose`` numbers the plan rows from 1; `twin
  calibrate` ignores it. ``approach`` is the direction each joint moved in to reach the pose:
  the capture goes through the plan in order, pose K from plan pose K − 1 (pose 1 from home),
  also when it resumes — as the simulated robot does; backlash depends on it. ``t_s`` is the
  time of the reading since the capture's first (:class:`RowClock`), ``reference`` the plan's
  flag of a revisit of its reference pose (`twin plan --reference-every`; 0 without one): what
  `twin calibrate`'s drift test reads.
- ``robot.toml`` (and ``robot.urdf`` for a robot read from a URDF), ``capture.toml`` — so that
  ``twin calibrate DIR/capture.toml`` needs nothing else (written atomically).
- ``.lock`` — an exclusive ``flock`` held while a capture runs (:mod:`twin.io.lock`); the
  kernel drops it when the process dies, even by SIGKILL, and the capture removes it when it
  ends.

Resume: running the same command again reads ``measurements.csv``, drops a partial last line
(a crash in the middle of a write, e.g. a power cut), and measures the plan poses that have no
row, in plan order. A crash, SIGKILL or Ctrl-C loses at most the pose in progress; a pose with a
row is never measured or written again.
"""

from __future__ import annotations

import contextlib
import math
import os
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from twin.calibration.settings import CalibrationSettings
from twin.dataset import REFERENCE, TIME, Measurements, approach_directions
from twin.errors import InputError, TwinError
from twin.hardware.capture_layout import (
    capture_columns,
    capture_header,
    row_columns,
    starts_as_journal,
)
from twin.hardware.encoders import EncoderConfig, open_encoder
from twin.hardware.encoders.base import Encoder, EncoderDisconnectedError
from twin.hardware.encoders.settle import Settled, SettleRule, settle
from twin.hardware.robot_sources.base import RobotSource
from twin.io.atomic import fsync_directory, write_atomic
from twin.io.capture_file import write_capture
from twin.io.journal import Journal
from twin.io.lock import folder_lock
from twin.io.measurements import (
    format_measurements,
    load_plan,
    read_table,
)
from twin.io.paths import os_error, read_bytes, read_text
from twin.io.robot_file import load_robot, robot_files
from twin.io.truth import TRUTH_FILE, write_truth
from twin.kinds.length import length_measurements
from twin.report.display import mm, seconds
from twin.rig import Rig
from twin.robot import RobotModel

CAPTURE_COLUMNS = capture_columns(6)
"""The columns of a 6-joint arm's capture."""
HEADER = capture_header(6)
"""The header of a 6-joint arm's capture."""
MEASUREMENTS_NAME = "measurements.csv"
PLAN_NAME = "plan.csv"
ROBOT_NAME = "robot.toml"
CAPTURE_NAME = "capture.toml"
CAPTURE_FILES = (MEASUREMENTS_NAME, PLAN_NAME, CAPTURE_NAME, ROBOT_NAME, "robot.urdf",
                 TRUTH_FILE)
"""What a capture folder holds (a robot read from a URDF: its reference and its URDF)."""
KEPT_PREFIX = "kept-"
JOURNAL = ("a capture measurement CSV (pose, q1..qN, length, t_s, reference, "
           "approach1..approachN)")
RECONNECT_POLL_S = 0.5
"""How often a lost port is tried again, s."""


def format_row(pose: int, q_rad: NDArray[np.float64], length_m: float,
               approach: NDArray[np.int8], robot: RobotModel | None = None, *,
               t_s: float = 0.0, reference: bool = False) -> str:
    """One line of the measurement file of ``robot`` (a prismatic joint's q in mm), with its
    LF; ``approach`` (n,) the pose's sides, ``t_s`` the reading's time since the capture's
    first, s, ``reference`` whether the pose is a revisit of the plan's reference pose."""
    length = length_measurements(q_rad[None, :], np.array([length_m]),
                                 approach=approach[None, :])
    rows = {TIME: np.array([t_s]), REFERENCE: np.array([float(reference)])}
    measured = Measurements(length.q_rad, length.kind, {**length.values, **rows},
                            length.labels, length.approach)
    return f"{pose},{format_measurements(measured, robot).splitlines()[1]}\n"


class RowClock:
    """Each row's ``t_s``: seconds since the capture's first reading.

    Within one run the time comes from the monotonic clock (a step of the wall clock does not
    move it). A resumed capture goes on from its journal: the last row's ``t_s`` plus the
    wall-clock time since that row was appended (the journal's modification time, set by the
    fsync-ed append), so the downtime between a kill and the resume counts — the arm cooled
    or warmed in it, which is what the drift test looks for. Derived from the journal rather
    than stored in its header: the header stays the plain CSV header every reader and the
    resume's header check take, and nothing beside the rows has to be kept in step with them.
    A wall-clock step across the downtime can only change that gap, clamped at 0: ``t_s``
    never goes back.
    """

    def __init__(self, start_s: float = 0.0, zero: float | None = None) -> None:
        self._start_s = start_s
        self._zero = zero

    @classmethod
    def resumed(cls, path: Path, written_epoch_s: float) -> RowClock:
        """The clock of a capture resumed on the journal ``path`` last appended to at
        ``written_epoch_s`` (s since the epoch)."""
        times = read_table(path, (TIME,), JOURNAL, journal=True)[0][:, 0]
        gap_s = max(0.0, time.time() - written_epoch_s)
        return cls(float(times.max()) + gap_s, time.monotonic())

    def __call__(self) -> float:
        """The time of a reading taken now, s (0 for a new capture's first)."""
        now = time.monotonic()
        if self._zero is None:
            self._zero = now
        return self._start_s + now - self._zero


def journal(path: Path, n_joints: int) -> Journal:
    """The measurement file of a capture of an ``n_joints`` arm, as a journal
    (:mod:`twin.io.journal`)."""
    return Journal(path, JOURNAL, capture_header(n_joints))


def recover(path: Path, n_poses: int, n_joints: int) -> tuple[set[int], str | None]:
    """The pose numbers already in a measurement file, after dropping a partial last line.

    Creates the file with its header if it does not exist.

    Returns:
        ``(done, note)``: measured pose numbers, and a note if a partial line was dropped.

    Raises:
        InputError: if a row's pose number is not an integer in 1..n_poses or is repeated.
    """
    whole, note = journal(path, n_joints).recover()
    if whole.count("\n") <= 1:
        return set(), note
    values, lines = read_table(path, row_columns(n_joints), JOURNAL, journal=True)
    done: set[int] = set()
    for number, line in zip(values[:, 0], lines, strict=True):
        pose = int(number)
        if pose != number or not 1 <= pose <= n_poses:
            raise InputError(f"{number!r}", f"a pose number in 1..{n_poses}", source=path,
                             where=f"line {line}, column pose")
        if pose in done:
            raise InputError(f"pose {pose} a second time", "each pose once", source=path,
                             where=f"line {line}")
        done.add(pose)
    return done, note


def locked(folder: Path) -> contextlib.AbstractContextManager[None]:
    """Hold the capture folder's lock (:mod:`twin.io.lock`), or fail at once if another
    command holds it."""
    return folder_lock(folder, "twin capture")


def check_folder(folder: Path, plan_path: Path, plan_q_rad: NDArray[np.float64],
                 robot: RobotModel) -> None:
    """Refuse, before anything is written, a folder that holds something else than a capture
    of this plan and robot (another capture, a `twin simulate` output, unrelated files).

    Raises:
        InputError: naming the file that belongs to something else.
    """
    resume = "the capture this folder was started with (or a new --out folder)"
    robot_text = "".join(robot_files(robot).values())
    stored_plan, stored_robot = folder / PLAN_NAME, folder / ROBOT_NAME
    if stored_plan.exists() and not np.array_equal(
            load_plan(stored_plan, robot, journal=True)[0], plan_q_rad):
        raise InputError(f"a capture of another plan than {plan_path}", resume,
                         source=stored_plan)
    # Written again by today's writer, so that a file of an older twin (unrounded numbers)
    # compares equal when it holds the same robot (a URDF robot: the reference and the URDF).
    if stored_robot.exists() and "".join(robot_files(load_robot(stored_robot)).values()) \
            != robot_text:
        raise InputError("a capture of another robot model", resume, source=stored_robot)
    measurements = folder / MEASUREMENTS_NAME
    if measurements.exists():
        first = read_bytes(measurements, JOURNAL, journal=True).split(b"\n", 1)
        head = first[0] + (b"\n" if len(first) > 1 else b"")
        header = capture_header(plan_q_rad.shape[1])
        if not header.encode("utf-8").startswith(head.lstrip()):
            # Its first line is not quoted: whatever file it is, its content stays its own.
            raise InputError("a measurement file of another kind (its first line is not a "
                             "capture's header)", f"the header {header.strip()} of a "
                             "capture, or a new --out folder", source=measurements,
                             where="line 1")


def real_measurements(folder: Path) -> tuple[Path, str] | None:
    """What makes ``folder`` hold real measurements, which only `twin capture` may write to:
    a capture's plan or journal, or a measurement file no simulation wrote (no truth.json
    beside it). None for a folder a simulation may write (new, or another simulation's).

    Returns:
        The file, and what it is.
    """
    plan, measurements = folder / PLAN_NAME, folder / MEASUREMENTS_NAME
    if starts_as_journal(measurements):
        return measurements, "a capture's measurements"
    if os.path.lexists(plan):
        return plan, "the plan of a capture"
    if os.path.lexists(measurements) and not (folder / TRUTH_FILE).exists():
        return measurements, "measurements no simulation wrote (no truth.json beside them)"
    return None


def set_aside(folder: Path) -> tuple[Path, list[str]]:
    """Move a capture's files out of the way, into a new ``folder/kept-<UTC time>/``; nothing
    is deleted.

    Returns:
        The new folder, and the names moved into it.
    """
    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
    kept = folder / f"{KEPT_PREFIX}{stamp}"
    suffix = 1
    while True:
        try:
            kept.mkdir()
            break
        except FileExistsError:
            suffix += 1
            kept = folder / f"{KEPT_PREFIX}{stamp}-{suffix}"
        except OSError as exc:
            raise os_error(kept, "creating it", exc, "a folder to write into") from None
    moved = [name for name in CAPTURE_FILES if os.path.lexists(folder / name)]
    try:
        for name in moved:
            os.rename(folder / name, kept / name)
        fsync_directory(kept)
        fsync_directory(folder)
    except OSError as exc:
        raise os_error(kept, "moving the capture into it", exc, "a folder to write into") \
            from None
    return kept, moved


def prepare(folder: Path, plan_path: Path, plan_q_rad: NDArray[np.float64],
            robot: RobotModel, source_files: Mapping[str, str] | None = None) -> None:
    """Store the plan, the robot model and the files the robot source needs (the RAPID plan
    module), or check they are those of the capture to resume.

    Raises:
        InputError: if ``folder`` holds something else (see :func:`check_folder`).
    """
    files = robot_files(robot)
    check_folder(folder, plan_path, plan_q_rad, robot)
    for name, text in ((PLAN_NAME, read_text(plan_path, "a pose plan CSV")), *files.items(),
                       *(source_files or {}).items()):
        if not (folder / name).exists():
            write_atomic(folder / name, text)
    fsync_directory(folder)


class CaptureError(TwinError):
    """The capture stopped on a fault; every row written before it stays."""


def measure(encoder: Encoder, rule: SettleRule, reconnect_s: float | None,
            report: Callable[[str], None]) -> Settled:
    """Settle one reading; if the port fails, reopen it for up to ``reconnect_s`` (None: until
    it comes back) and retry.

    Raises:
        EncoderDisconnectedError: if the device does not come back in time.
    """
    if reconnect_s is not None and not 0 <= reconnect_s < math.inf:
        raise ValueError(f"reconnect_s: {reconnect_s}, expected a finite time >= 0 or None")
    while True:
        try:
            return settle(encoder.read_m, rule,
                          on_failure=lambda exc: report(f"  retrying: {exc}"))
        except EncoderDisconnectedError as lost:
            limit = "until it comes back" if reconnect_s is None else f"for {reconnect_s:g} s"
            report(f"  {lost}; trying to reopen {limit}")
            deadline = math.inf if reconnect_s is None else time.monotonic() + reconnect_s
            while True:
                try:
                    encoder.open()
                    break
                except EncoderDisconnectedError:
                    if time.monotonic() >= deadline:
                        raise lost from None
                    time.sleep(RECONNECT_POLL_S if reconnect_s is None
                               else min(RECONNECT_POLL_S, reconnect_s))


def capture(
    plan_q_rad: NDArray[np.float64],
    measurements_path: Path,
    encoder: Encoder,
    robot: RobotSource,
    rule: SettleRule,
    *,
    reconnect_s: float | None = 5.0,
    report: Callable[[str], None] = print,
    nominal: RobotModel | None = None,
    reference: NDArray[np.bool_] | None = None,
) -> int:
    """Measure every plan pose that has no row yet, appending each row durably.

    Args:
        plan_q_rad: Plan, shape (N, n), rad.
        measurements_path: The measurement CSV (created with its header if absent).
        encoder: The open encoder.
        robot: Where the joint angles come from.
        rule: When a reading counts as settled.
        reconnect_s: How long to try reopening a port that failed, s (None: until it comes
            back).
        report: Receives progress and fault lines.
        nominal: The robot measured (its prismatic joints' values are written in mm); every
            joint revolute if None.
        reference: The plan's revisits of its reference pose, shape (N,); none if None.

    Returns:
        The number of poses measured by this call.

    Raises:
        CaptureError: on a fault that retries did not cure; every row written so far stays.
        KeyboardInterrupt: on Ctrl-C, after reporting how to resume.
    """
    n_poses, n_joints = plan_q_rad.shape
    # Taken before a torn line's repair rewrites the file.
    written = measurements_path.stat().st_mtime if measurements_path.exists() else 0.0
    done, note = recover(measurements_path, n_poses, n_joints)
    clock = RowClock.resumed(measurements_path, written) if done else RowClock()
    flags = np.zeros(n_poses, dtype=bool) if reference is None else reference
    record = journal(measurements_path, n_joints)
    if note:
        report(note)
    todo = [pose for pose in range(1, n_poses + 1) if pose not in done]
    if done:
        start = f"resuming at pose {todo[0]}/{n_poses}" if todo else "nothing left to measure"
        report(f"{len(done)} of {n_poses} poses already in {measurements_path}; {start}")
    pose = todo[0] if todo else 0
    approach = approach_directions(plan_q_rad)
    try:
        for pose in todo:
            started = time.monotonic()
            try:
                q_reached = robot.move_to(pose, n_poses, plan_q_rad[pose - 1])
                settled = measure(encoder, rule, reconnect_s, report)
            except TwinError as exc:
                raise _stopped(exc, pose, done, n_poses) from None
            record.append(format_row(pose, q_reached, settled.length_m, approach[pose - 1],
                                     nominal, t_s=clock(), reference=bool(flags[pose - 1])))
            done.add(pose)
            try:
                robot.recorded(pose, n_poses)
            except TwinError as exc:
                raise _stopped(exc, pose, done, n_poses) from None
            report(f"pose {pose}/{n_poses}: {mm(settled.length_m)} "
                   f"({settled.readings} readings, spread {mm(settled.spread_m)}, "
                   f"{seconds(time.monotonic() - started, 2)})")
    except KeyboardInterrupt:
        report(f"interrupted at pose {pose}/{n_poses}. {_saved(done, n_poses)}")
        raise
    return len(todo)


def capture_folder(
    folder: Path,
    plan_path: Path,
    plan_q_rad: NDArray[np.float64],
    robot: RobotModel,
    rig: Rig,
    config: EncoderConfig,
    source: RobotSource,
    rule: SettleRule,
    *,
    calibration: CalibrationSettings | None = None,
    truth: Mapping[str, Any] | None = None,
    source_files: Mapping[str, str] | None = None,
    reconnect_s: float | None = 5.0,
    report: Callable[[str], None] = print,
    reference: NDArray[np.bool_] | None = None,
) -> int:
    """Measure a plan into a capture folder, resuming what is there: check the folder, lock it,
    open the encoder, copy the plan and write the robot, the robot source's files (named in a
    report line), the truth (when the virtual encoder serves a scenario) and ``capture.toml``,
    then :func:`capture` every pose not yet measured.

    Args:
        folder: The capture folder (created).
        plan_path: The plan CSV, copied into the folder.
        plan_q_rad: Its poses, shape (N, n), rad.
        robot: The nominal robot (a model file or a URDF, 4 to 9 joints).
        rig: The rig as told: the encoder's one port (base frame, m), the cable's attachment
            point (flange frame, m) and its tension (N), written to ``capture.toml``.
        config: How to talk to the encoder.
        source: Where the joint angles come from.
        rule: When a reading counts as settled.
        calibration: How the capture asks to be calibrated (a scenario's ``[calibration]``
            and the cable's tension), or None for the defaults.
        truth: The twin's truth, written as truth.json, or None.
        source_files: Files the robot source needs in the folder (name to text).
        reconnect_s: As in :func:`capture`.
        report: Receives progress and fault lines.
        reference: As in :func:`capture`.

    Returns:
        The number of poses measured by this call.

    Raises:
        InputError: if the folder holds another plan or robot, or another capture runs in it.
        CaptureError: as :func:`capture`.
    """
    check_folder(folder, plan_path, plan_q_rad, robot)
    with locked(folder), open_encoder(config) as encoder:
        prepare(folder, plan_path, plan_q_rad, robot, source_files)
        # Named once written, the encoder open: the operator loads it into the controller
        # while the capture waits for the first pose.
        for name in source_files or {}:
            report(f"the robot program for this plan: {folder / name}")
        if truth is not None:
            write_truth(folder / TRUTH_FILE, truth)
        write_capture(folder / CAPTURE_NAME, robot=ROBOT_NAME, rig=rig,
                      measurements=MEASUREMENTS_NAME, calibration=calibration,
                      truth=TRUTH_FILE if truth is not None else None,
                      encoder={"url": config.to_url()})
        return capture(plan_q_rad, folder / MEASUREMENTS_NAME, encoder, source, rule,
                       reconnect_s=reconnect_s, report=report, nominal=robot,
                       reference=reference)


def _stopped(exc: TwinError, pose: int, done: set[int], n_poses: int) -> TwinError:
    """The error that stops a capture at ``pose``, saying what is saved: a user's mistake met
    on the way (credentials the controller refused) stays one (exit code 2), anything else is
    a fault of the cell (:class:`CaptureError`, exit code 1)."""
    if isinstance(exc, InputError):
        return InputError(f"{exc.found} (at pose {pose}/{n_poses})",
                          f"{exc.expected}. {_saved(done, n_poses)}", source=exc.source,
                          where=exc.where)
    return CaptureError(f"pose {pose}/{n_poses}: {exc}. {_saved(done, n_poses)}")


def _saved(done: set[int], n_poses: int) -> str:
    return (f"{len(done)} of {n_poses} poses are saved; run the same command again to resume "
            "(measured poses are kept and not repeated)")
