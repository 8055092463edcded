"""The robot-source interface: bring the robot to a plan pose and say where it really is; and
what a source is told when it is opened (:class:`SourceRequest`) and how it registers
(:class:`SourceKind`)."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple, TextIO

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from twin.calibration.settings import CalibrationSettings
    from twin.hardware.rws.client import RwsConnection
    from twin.rig import Rig
    from twin.robot import RobotModel


class RobotSource(ABC):
    """Where the joint angles of each captured pose come from.

    Poses are numbered from 1, as shown to the operator (``pose K/N``) and written to the
    ``pose`` column of the measurement file.
    """

    @abstractmethod
    def move_to(self, pose: int, n_poses: int, target_q_rad: NDArray[np.float64]
                ) -> NDArray[np.float64]:
        """Bring the robot to a plan pose and return the joint angles it reached.

        Args:
            pose: Pose number K, 1..N.
            n_poses: Number of plan poses N.
            target_q_rad: The plan's joint angles, shape (n,), rad.

        Returns:
            The joint angles reached (what the controller reports), shape (n,), rad.
        """

    def recorded(self, pose: int, n_poses: int) -> None:  # noqa: B027 (most sources need none)
        """The row of ``pose`` is on disk: a controller waiting for it may move on."""

    def close(self) -> None:  # noqa: B027 (most sources hold nothing)
        """Release what the source holds (a controller session)."""


@dataclass(frozen=True)
class SourceRequest:
    """What the capture tells a robot source when it opens it.

    Attributes:
        spec: The ``--robot-source`` value (``sim``, ``manual``, ``file``,
            ``rws://HOST[:PORT]``, ``rws2://HOST[:PORT]``).
        plan_q_rad: The plan, shape (N, n), rad (m for a prismatic joint; filled in once the
            plan is read).
        prismatic: Which of the robot's joints slide (their values in mm wherever the source
            shows, reads or writes them, degrees for the others); filled in with the plan,
            every joint revolute if empty.
        pose_file: sim: the channel to the virtual encoder (None: the default file).
        joint_log: file: the controller's log.
        joint_log_wait_s: file: how long to wait for a pose's row (None: until it comes).
        prompt_out, answers_in: manual: the operator's terminal.
        rws: rws, rws2: how to reach the controller (credentials, TLS).
        options: Settings of one source that the others do not read, by name.
    """

    spec: str
    plan_q_rad: NDArray[np.float64] = field(default_factory=lambda: np.empty((0, 0)))
    prismatic: tuple[bool, ...] = ()
    pose_file: Path | None = None
    joint_log: Path | None = None
    joint_log_wait_s: float | None = 60.0
    prompt_out: TextIO | None = None
    answers_in: TextIO | None = None
    rws: RwsConnection | None = None
    options: Mapping[str, Any] = field(default_factory=dict)


class Cell(NamedTuple):
    """What a source that simulates the whole cell brings with it (the twin's scenario)."""

    robot: RobotModel
    """The nominal robot."""
    rig: Rig
    """The rig as told."""
    truth: Mapping[str, Any]
    """The twin's truth, written as truth.json."""
    calibration: CalibrationSettings | None
    """How the capture asks to be calibrated."""


@dataclass(frozen=True)
class SourceKind:
    """One robot source, as the registry (:mod:`twin.hardware.robot_sources`) knows it.

    Attributes:
        name: The ``--robot-source`` value, or the URL scheme (``rws``).
        summary: One line for the help text.
        open: Opens the source for a capture.
        cell: For a source that simulates the cell: its robot, rig and truth from the
            scenario and seed (the capture then takes no ``--robot``/``--port``), else None.
        files: Files the source needs in the capture folder (name to text; the RAPID plan
            module of an ABB controller), or None.
    """

    name: str
    summary: str
    open: Callable[[SourceRequest], RobotSource]
    cell: Callable[[Path | None, int | None], Cell] | None = None
    files: Callable[[SourceRequest], dict[str, str]] | None = None
