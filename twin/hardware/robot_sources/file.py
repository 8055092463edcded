"""Joint values logged by the robot controller, matched to the plan by pose number.

The controller (e.g. a RAPID program running the plan) appends one CSV row per pose once the
robot stands still: ``pose,q1,…,qN`` with q in degrees, mm for a prismatic joint (other columns
are ignored), one whole line per write. The capture waits for the row of each pose to appear,
then reads the encoder.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from twin.errors import InputError
from twin.hardware.robot_sources.base import RobotSource, SourceKind, SourceRequest
from twin.io.measurements import joint_columns, read_table
from twin.io.paths import read_bytes
from twin.units import joints_from_file

POSE_COLUMN = "pose"


class FileRobot(RobotSource):
    """Reads the reached joint angles from the controller's log.

    Args:
        path: The controller's CSV log.
        wait_s: How long to wait for a pose's row to appear, s; None waits until it does.
        poll_s: How often to look again, s.
        n_joints: The robot's joints (the log's columns q1..qN).
        prismatic: Which joints slide (logged in mm), shape (n,); none if empty.
    """

    def __init__(self, path: str | Path, wait_s: float | None = 0.0,
                 poll_s: float = 0.2, n_joints: int = 6,
                 prismatic: tuple[bool, ...] = ()) -> None:
        self.path, self.wait_s, self.poll_s = Path(path), wait_s, poll_s
        self.columns = joint_columns(n_joints)
        self.prismatic = prismatic or None

    def _logged(self) -> dict[int, NDArray[np.float64]]:
        """Pose number -> joint values as logged (degrees, mm), shape (n,); empty if there is
        no log yet."""
        if not self.path.exists():
            return {}
        sliding = [name for name, slides in zip(self.columns, self.prismatic or (), strict=False)
                   if slides]
        what = (f"a controller log CSV (pose, q1..q{len(self.columns)} in deg"
                + (f", {','.join(sliding)} in mm)" if sliding else ")"))
        text = read_bytes(self.path, what).splitlines()
        if sum(1 for line in text if line.strip() and not line.lstrip().startswith(b"#")) < 2:
            return {}  # the controller has not logged a pose yet
        values, lines = read_table(self.path, (POSE_COLUMN, *self.columns), what)
        logged: dict[int, NDArray[np.float64]] = {}
        for row, line in zip(values, lines, strict=True):
            pose = int(row[0])
            if pose != row[0] or pose < 1:
                raise InputError(f"{row[0]!r}", "a pose number 1, 2, …", source=self.path,
                                 where=f"line {line}, column pose")
            logged[pose] = row[1:]
        return logged

    def move_to(self, pose: int, n_poses: int, target_q_rad: NDArray[np.float64]
                ) -> NDArray[np.float64]:
        """The logged angles of this pose, waiting up to ``wait_s`` for them."""
        deadline = math.inf if self.wait_s is None else time.monotonic() + self.wait_s
        while (q_file := self._logged().get(pose)) is None:
            if time.monotonic() >= deadline:
                raise InputError(f"no row for pose {pose}/{n_poses}",
                                 f"a row 'pose={pose},q1..q{len(self.columns)}' logged by the "
                                 "controller "
                                 f"(waited {self.wait_s:g} s)", source=self.path)
            time.sleep(self.poll_s)
        return joints_from_file(q_file, self.prismatic)


def _open(request: SourceRequest) -> RobotSource:
    if request.joint_log is None:
        raise InputError("no --joint-log", "the controller's log CSV (--robot-source file)",
                         source="command line")
    return FileRobot(request.joint_log, wait_s=request.joint_log_wait_s,
                     n_joints=request.plan_q_rad.shape[1], prismatic=request.prismatic)


KIND = SourceKind("file", "joint angles logged by the controller (--joint-log)", _open)
