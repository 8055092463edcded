"""The simulated robot: its controller publishes the commanded pose for the virtual encoder.

The channel is a small JSON file, replaced atomically at each move (default
:data:`DEFAULT_POSE_FILE`)::

    {"pose": 7, "q_deg": [10, -20, 5, 0, 30, 0], "from_q_deg": [...], "command": "3f2a…"}

``twin virtual-encoder`` reads it at each query, so the length it answers is the twin's length at
the pose the robot was last sent to. ``command`` changes at every move, even back to the same
pose: the encoder restarts its settling transient and its per-pose noise sequence there.

The robot approaches pose K from plan pose K − 1 (pose 1 from home, q = 0), also when a capture
resumes: backlash then acts as in an uninterrupted run, and the same capture reads the same
lengths. The joints reach the commanded angles up to the twin's joint errors.
"""

from __future__ import annotations

import json
import os
import tempfile
import uuid
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from twin.errors import InputError
from twin.hardware.robot_sources.base import Cell, RobotSource, SourceKind, SourceRequest
from twin.io.atomic import write_atomic
from twin.io.paths import read_text
from twin.units import joints_from_file, joints_to_file

DEFAULT_POSE_FILE = Path(tempfile.gettempdir()) / f"twin-sim-pose-{os.getuid()}.json"
"""Where the simulated controller publishes its pose unless told otherwise."""


class CommandedPose(NamedTuple):
    """The pose the simulated robot was last sent to."""

    pose: int
    """Pose number, from 1."""
    q_rad: NDArray[np.float64]
    """Joint values, shape (n,), rad (m for a prismatic joint)."""
    from_q_rad: NDArray[np.float64]
    """Where the robot came from, shape (n,), rad (m) (sets the backlash side)."""
    command: str
    """Identifier of this move."""


def publish_pose(path: str | Path, pose: int, q_rad: NDArray[np.float64],
                 from_q_rad: NDArray[np.float64], prismatic: tuple[bool, ...] = ()) -> None:
    """Replace the pose file atomically with a new move: ``q`` and ``from_q`` as files write
    joint values (degrees, mm for the ``prismatic`` joints)."""
    mask = prismatic or None
    document = {"pose": pose, "q": joints_to_file(q_rad, mask).tolist(),
                "from_q": joints_to_file(from_q_rad, mask).tolist(), "command": uuid.uuid4().hex}
    write_atomic(path, json.dumps(document) + "\n")


def read_pose(path: str | Path, prismatic: tuple[bool, ...] = ()) -> CommandedPose | None:
    """The last published move (its ``prismatic`` joints' values in mm), or None if the robot
    was never moved.

    Raises:
        InputError: if the file is not a pose file.
    """
    if not Path(path).exists():
        return None
    text = read_text(path, "a pose file written by twin capture --robot-source sim",
                     journal=True)
    try:
        document = json.loads(text)
        mask = prismatic or None
        return CommandedPose(int(document["pose"]), joints_from_file(document["q"], mask),
                             joints_from_file(document["from_q"], mask),
                             str(document["command"]))
    except (ValueError, KeyError, TypeError):
        raise InputError("a file that is not a pose file", 'a pose file {"pose", "q", '
                         '"from_q", "command"}', source=path) from None


class SimRobot(RobotSource):
    """The twin's robot: moves by publishing the commanded pose.

    Args:
        plan_q_rad: The plan, shape (N, n), rad (m): pose K is approached from pose K − 1.
        pose_file: The channel to the virtual encoder.
        prismatic: Which joints slide, shape (n,); none if empty.
    """

    def __init__(self, plan_q_rad: NDArray[np.float64],
                 pose_file: str | Path = DEFAULT_POSE_FILE,
                 prismatic: tuple[bool, ...] = ()) -> None:
        self.plan_q_rad = np.asarray(plan_q_rad, dtype=np.float64)
        self.pose_file = Path(pose_file)
        self.prismatic = prismatic

    def move_to(self, pose: int, n_poses: int, target_q_rad: NDArray[np.float64]
                ) -> NDArray[np.float64]:
        """Publish the move; the controller reports the commanded angles."""
        home = np.zeros(self.plan_q_rad.shape[1])
        publish_pose(self.pose_file, pose, target_q_rad,
                     self.plan_q_rad[pose - 2] if pose > 1 else home, self.prismatic)
        return np.asarray(target_q_rad, dtype=np.float64)


def scenario_cell(scenario: Path | None, seed: int | None) -> Cell:
    """The robot, the told rig and the truth of the scenario the virtual encoder serves: those
    of :func:`twin.sim.simulate` for the same scenario and seed.

    Raises:
        InputError: without a scenario, or for one that is not of one cable port.
    """
    if scenario is None:
        raise InputError("no --scenario", "the scenario the virtual encoder serves "
                         "(--robot-source sim)", source="command line")
    from twin.scenario import load_scenario
    from twin.sim import simulate

    sim = simulate(load_scenario(scenario), seed)
    if sim.port_m is None or sim.port_nominal_m is None or len(sim.rig.ports_m) > 1:
        raise InputError(f"a {sim.measurements.kind} scenario with {len(sim.rig.ports_m)} "
                         "ports", "a scenario of one cable port (the virtual encoder serves "
                         "one cable)", source=scenario)
    return Cell(sim.robot, sim.rig_told_pulled, sim.capture_truth, sim.scenario.calibration)


def _open(request: SourceRequest) -> RobotSource:
    return SimRobot(request.plan_q_rad, request.pose_file or DEFAULT_POSE_FILE,
                    request.prismatic)


KIND = SourceKind("sim", "the twin moves (with twin virtual-encoder)", _open,
                  cell=scenario_cell)
