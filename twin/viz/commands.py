"""What `twin simulate`, `twin calibrate` and `twin study` call to record what the
``--rerun-*`` flags (:mod:`twin.viz.options`) ask for.

This module does not import ``rerun``: the CLI runs without it, and the recording modules are
imported only when a flag asks for them.
"""

from __future__ import annotations

import argparse
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from twin.dataset import Measurements
from twin.viz.options import rerun_options

if TYPE_CHECKING:
    from twin.rig import Rig
    from twin.robot import RobotModel
    from twin.sim import Simulation
    from twin.viz.calibration_log import CalibrationLog
    from twin.viz.recording import Recording


@contextmanager
def open_from_args(
    args: argparse.Namespace, name: str, fallback_dir: Path | None = None
) -> Iterator[Recording | None]:
    """Open the recording the flags ask for, or yield None when there is no ``--rerun-*`` flag.

    Leaving the block flushes and closes the recording; with ``--rerun-serve`` it first keeps
    serving until Ctrl-C.

    Args:
        args: Parsed arguments of a parser that went through :func:`add_rerun_flags`.
        name: The command (``"calibrate"``…): the recording's name and the fallback file's.
        fallback_dir: Where to save when the viewer cannot be spawned (default: current folder).
    """
    options = rerun_options(args)
    if not options.enabled:
        yield None
        return
    from twin.viz.recording import open_recording

    with open_recording(options, name, fallback_dir=fallback_dir) as recording:
        yield recording


@contextmanager
def calibration_log(
    args: argparse.Namespace,
    methods: Sequence[str],
    robot: RobotModel,
    rig: Rig,
    measurements: Measurements,
    truth_delta: NDArray[np.float64] | None = None,
    *,
    fallback_dir: Path | None = None,
) -> Iterator[CalibrationLog | None]:
    """What `twin calibrate` opens before it calibrates, if a ``--rerun-*`` flag asks for it:
    the setup is logged at once, each method when it finishes, so a viewer shows the run live.

    Yields None without a flag. The caller adds each result and finishes the log.

    Args:
        args: The parsed arguments.
        methods: The methods' names, in the order they will run.
        robot: The nominal robot.
        rig: The rig the calibration is told.
        measurements: Every measured pose (train and validation).
        truth_delta: True D-H errors, shape (4, n), m and rad, if known.
        fallback_dir: Where to save when the viewer cannot be spawned.
    """
    with open_from_args(args, "calibrate", fallback_dir) as recording:
        if recording is None:
            yield None
            return
        yield recording.start_calibration(methods, robot, rig, measurements,
                                          truth_delta=truth_delta)


def record_simulation(args: argparse.Namespace, sim: Simulation) -> None:
    """What `twin simulate` calls: log the simulated capture if a ``--rerun-*`` flag asks.

    Logs the nominal and the true robot in every recorded pose, the true ports and the cable to
    the true robot's measured point (or the measured points) and a short report; a spawn
    fallback file goes to ``args.out``.
    """
    with open_from_args(args, "simulate", args.out) as recording:
        if recording is None:
            return
        from twin.viz.recording_report import scene_markdown

        recording.log_scene({"nominal": sim.robot, "true": sim.true_robot}, sim.measurements,
                            sim.rig, cable_to="true")
        recording.log_report(scene_markdown(sim.robot, sim.measurements, sim.rig, sim.delta))
