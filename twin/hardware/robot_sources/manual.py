"""The operator jogs the robot to each pose and confirms on the terminal.

For each pose the terminal shows ``pose K/N`` and the target joint angles; the operator jogs the
robot there and presses Enter (the target was reached) or types the n joint angles the teach
pendant shows, in degrees, separated by spaces or commas.
"""

from __future__ import annotations

import re
import sys
from typing import TextIO

import numpy as np
from numpy.typing import NDArray

from twin.errors import TwinError
from twin.hardware.robot_sources.base import RobotSource, SourceKind, SourceRequest
from twin.report.display import JOINT_ANGLE_DECIMALS, joint_values
from twin.units import joints_from_file


class ManualRobot(RobotSource):
    """Asks the operator at each pose.

    Args:
        prompt_out: Where the prompts go (the terminal).
        answers_in: Where the operator's answers come from.
        prismatic: Which joints slide (shown and typed in mm), shape (n,); none if empty.
    """

    def __init__(self, prompt_out: TextIO, answers_in: TextIO,
                 prismatic: tuple[bool, ...] = ()) -> None:
        self.prompt_out, self.answers_in = prompt_out, answers_in
        self.prismatic = prismatic or None

    def move_to(self, pose: int, n_poses: int, target_q_rad: NDArray[np.float64]
                ) -> NDArray[np.float64]:
        """Show the target, wait for Enter or for the joint values reached."""
        n = target_q_rad.shape[0]
        sliding = np.zeros(n, dtype=bool) if self.prismatic is None else self.prismatic
        target, unit = joint_values(target_q_rad, sliding, JOINT_ANGLE_DECIMALS, separator=" ")
        while True:
            self.prompt_out.write(
                f"pose {pose}/{n_poses}: jog to q = [{target}] {unit}, then press Enter "
                f"(or type the {n} joint values reached, {unit}): "
            )
            self.prompt_out.flush()
            answer = self.answers_in.readline()
            if not answer:
                raise TwinError(f"pose {pose}/{n_poses}: the terminal closed before the pose "
                                "was confirmed")
            fields = [f for f in re.split(r"[\s,;]+", answer.strip()) if f]
            if not fields:
                return np.asarray(target_q_rad, dtype=np.float64)
            try:
                reached = np.array([float(f) for f in fields])
            except ValueError:
                reached = np.full(0, np.nan)
            if reached.shape == (n,) and np.all(np.isfinite(reached)):
                return joints_from_file(reached, self.prismatic)
            self.prompt_out.write(f"  found {answer.strip()!r}, expected Enter or {n} numbers "
                                  f"({unit}); try again\n")


def _open(request: SourceRequest) -> RobotSource:
    return ManualRobot(request.prompt_out or sys.stdout, request.answers_in or sys.stdin,
                       request.prismatic)


KIND = SourceKind("manual", "the operator jogs and confirms on the terminal", _open)
