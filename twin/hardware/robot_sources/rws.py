"""An ABB controller over Robot Web Services: ``rws://HOST[:PORT]`` (IRC5, RWS 1.0) and
``rws2://HOST[:PORT]`` (OmniCore, RWS 2.0).

Two ways of running a plan:

- **the plan module** (default): the controller runs the RAPID module of
  :mod:`twin.io.rapid_handshake` (written into the capture folder as ``TwinPlan.mod``). For each
  pose twin reads ``twin_ready``, then ``twin_pose`` and ``twin_ack``; a pose waits for twin while
  ready is TRUE and ack differs from pose. A pose before the one twin wants is one it already
  has: twin acknowledges it at once (a resumed capture, a restarted program). Once the pose's row
  is on disk twin writes ``twin_ack``, and the robot moves on: a whole plan unattended.
- **jogging** (``jog``): no program runs; the operator jogs to each pose and twin reads the joints
  once they stand still within the tolerance of it. Nobody types.

Either way the joints are read from the mechanical unit (``ROB_1``'s jointtarget) until they
stand still — every value within :attr:`RwsCapture.standstill_tol_deg` over
:attr:`RwsCapture.standstill_s` — and checked against the plan's pose within
:attr:`RwsCapture.joint_tol_deg`; the values read are recorded (joints 1..6 from rax_1..rax_6, a
7th from eax_a).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from twin.errors import TwinError
from twin.hardware.robot_sources.base import RobotSource, SourceKind, SourceRequest
from twin.hardware.rws.client import RefusedError, RwsClient
from twin.io.rapid_handshake import (
    ACK_SYMBOL,
    MODULE,
    POSE_SYMBOL,
    READY_SYMBOL,
    TASK,
    joints_deg,
    module_text,
)
from twin.report.display import deg, joint_angles, seconds
from twin.units import deg_to_rad, rad_to_deg

WAITING_NOTE_S = 2.0
"""After this long without the robot at the pose, say what twin waits for, s."""


@dataclass(frozen=True)
class RwsCapture:
    """How a capture reads an ABB controller.

    Attributes:
        joint_tol_deg: Largest difference between a joint read and the plan's, degrees.
        standstill_s: How long the joints must stay within ``standstill_tol_deg``, s.
        standstill_tol_deg: Largest spread of a joint over that window, degrees.
        poll_s: Pause between two reads of the controller, s.
        wait_s: Longest wait for the robot to stand at a pose, s (None: until it does).
        jog: The operator jogs (no plan module runs).
        task, module: Where the plan module runs.
    """

    joint_tol_deg: float = 0.05
    standstill_s: float = 0.3
    standstill_tol_deg: float = 0.001
    poll_s: float = 0.02
    wait_s: float | None = 120.0
    jog: bool = False
    task: str = TASK
    module: str = MODULE

    def __post_init__(self) -> None:
        for name in ("joint_tol_deg", "standstill_s", "standstill_tol_deg", "poll_s"):
            if not 0 < getattr(self, name) < math.inf:
                raise ValueError(f"{name}: {getattr(self, name)}, expected a positive number")


class RwsRobot(RobotSource):
    """The robot as an ABB controller reports it (see the module docstring).

    Args:
        client: A session with the controller.
        n_joints: Joints of the arm.
        settings: Tolerances and waits.
        report: Receives the prompts and waiting notes.
    """

    def __init__(self, client: RwsClient, n_joints: int, settings: RwsCapture,
                 report: Callable[[str], None] = print) -> None:
        self.client, self.n_joints, self.settings, self.report = client, n_joints, settings, report
        self._ran = False

    def _symbol(self, name: str) -> str:
        return self.client.symbol(self.settings.task, self.settings.module, name)

    def _waiting_pose(self) -> int | None:
        """The pose the plan module waits at for twin, or None; whether it runs at all."""
        try:
            ready = self._symbol(READY_SYMBOL).strip().upper() == "TRUE"
            pose, ack = (int(float(self._symbol(name))) for name in (POSE_SYMBOL, ACK_SYMBOL))
        except RefusedError:
            if self._ran:
                raise
            return None  # the module is not loaded yet: its symbols are unknown
        self._ran = True
        return pose if ready and pose >= 1 and pose != ack else None

    def _deadline(self) -> float:
        return math.inf if self.settings.wait_s is None \
            else time.monotonic() + self.settings.wait_s

    def _handshake(self, pose: int, n_poses: int) -> None:
        """Wait until the plan module stands at ``pose``, acknowledging poses twin has."""
        started, deadline, waiting_told = time.monotonic(), self._deadline(), False
        while True:
            waiting = self._waiting_pose()
            if waiting is not None and waiting < pose:
                # Every pose before the one the capture wants has its row (it goes in order).
                self.client.set_symbol(self.settings.task, self.settings.module, ACK_SYMBOL,
                                       str(waiting))
                continue
            if waiting is not None and waiting > pose:
                raise TwinError(f"the plan module stands at pose {waiting}, but pose {pose} is "
                                "not measured: set the program pointer to main and start it "
                                "again (poses twin has are acknowledged at once)")
            if waiting == pose:
                return
            if self._ran and self.client.execution_state() == "stopped":
                raise TwinError(f"the controller stopped the plan module before standing at "
                                f"pose {pose}/{n_poses} (RAPID execution stopped): it refused "
                                "the pose, or was stopped; see its event log")
            if not waiting_told and time.monotonic() - started > WAITING_NOTE_S:
                self.report(f"waiting for the plan module {self.settings.module} in "
                            f"{self.settings.task} to stand at pose {pose}/{n_poses}")
                waiting_told = True
            if time.monotonic() >= deadline:
                raise TwinError(f"the controller did not stand at pose {pose}/{n_poses} within "
                                f"{self.settings.wait_s:g} s ({READY_SYMBOL} stayed FALSE)")
            time.sleep(self.settings.poll_s)

    def _standstill(self, pose: int, n_poses: int, deadline: float) -> NDArray[np.float64]:
        """The joints, degrees (n,), once they stayed within the tolerance for the window.

        Raises:
            TwinError: if they did not stand still before the deadline.
        """
        samples: list[tuple[float, NDArray[np.float64]]] = []
        window = self.settings.standstill_s
        while True:
            now = time.monotonic()
            samples.append((now, joints_deg(self.client.axes_deg(), self.n_joints)))
            while len(samples) > 1 and now - samples[1][0] >= window:
                samples.pop(0)
            values = np.array([q for _, q in samples])
            spread = values.max(axis=0) - values.min(axis=0)
            if now - samples[0][0] >= window and np.all(spread <= self.settings.standstill_tol_deg):
                return values[-1]
            if now >= deadline:
                joint = int(np.argmax(spread))
                raise TwinError(f"pose {pose}/{n_poses}: the joints did not stand still within "
                                f"{self.settings.wait_s:g} s: joint {joint + 1} moved "
                                f"{deg(deg_to_rad(spread[joint]))} over "
                                f"{seconds(now - samples[0][0], 2)} "
                                f"(at most {self.settings.standstill_tol_deg:g} deg over "
                                f"{window:g} s)")
            time.sleep(self.settings.poll_s)

    def move_to(self, pose: int, n_poses: int, target_q_rad: NDArray[np.float64]
                ) -> NDArray[np.float64]:
        """Wait for the robot to stand at the pose; its joint values, checked against it."""
        target_deg = rad_to_deg(np.asarray(target_q_rad, dtype=np.float64))
        tolerance = self.settings.joint_tol_deg
        if self.settings.jog:
            self.report(f"pose {pose}/{n_poses}: jog to q = {joint_angles(target_q_rad)}; "
                        f"twin reads the joints once they stand still within {tolerance:g} deg "
                        "of it")
        else:
            self._handshake(pose, n_poses)
        deadline = self._deadline()
        while True:
            reached = self._standstill(pose, n_poses, deadline)
            off = np.abs(reached - target_deg)
            if np.all(off <= tolerance):
                return deg_to_rad(reached)
            joint = int(np.argmax(off))
            where = (f"pose {pose}/{n_poses}: the robot stands {deg(deg_to_rad(off[joint]))} "
                     f"from the plan on joint {joint + 1} (q = "
                     f"{joint_angles(deg_to_rad(reached))}; tolerance {tolerance:g} deg)")
            if not self.settings.jog:
                raise TwinError(f"{where}: is the plan module the one of this plan?")
            if time.monotonic() >= deadline:
                raise TwinError(f"{where} after {self.settings.wait_s:g} s")
            self.report(f"  {where}; keep jogging")
            time.sleep(self.settings.standstill_s)

    def recorded(self, pose: int, n_poses: int) -> None:
        """Acknowledge the pose: the plan module moves on."""
        if not self.settings.jog:
            self.client.set_symbol(self.settings.task, self.settings.module, ACK_SYMBOL,
                                   str(pose))

    def close(self) -> None:
        """Log out of the controller."""
        self.client.close()


def _settings(request: SourceRequest) -> RwsCapture:
    """The capture settings a request carries (``options["rws"]``), or the defaults."""
    settings = request.options.get("rws", RwsCapture())
    if not isinstance(settings, RwsCapture):
        raise TypeError("options['rws']: expected RwsCapture")
    return settings


def _open(request: SourceRequest) -> RobotSource:
    from twin.hardware.rws.client import RwsConnection

    connection = request.rws or RwsConnection.from_spec(request.spec)
    settings = _settings(request)
    out = request.prompt_out

    def report(line: str) -> None:
        if out is None:
            print(line, flush=True)
        else:
            out.write(line + "\n")
            out.flush()

    return RwsRobot(RwsClient(connection), request.plan_q_rad.shape[1], settings, report)


def _files(request: SourceRequest) -> dict[str, str]:
    settings = _settings(request)
    if settings.jog:
        return {}
    return {f"{settings.module}.mod": module_text(request.plan_q_rad, name=settings.module)}


KIND = SourceKind("rws", "an IRC5 over Robot Web Services 1.0 (HTTP, digest)", _open,
                  files=_files)
KIND2 = SourceKind("rws2", "an OmniCore over Robot Web Services 2.0 (HTTPS, basic)", _open,
                   files=_files)
