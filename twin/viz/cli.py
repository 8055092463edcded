"""The ``--rerun-*`` flags shared by `twin simulate`, `twin calibrate` and `twin study`.

This module does not import ``rerun``: the CLI builds its parser and runs without it, and the
recording modules are imported only when a flag asks for them.
"""

from __future__ import annotations

import argparse
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from twin.dataset import Measurements
from twin.io.paths import OutputFile

if TYPE_CHECKING:
    from twin.rig import Rig
    from twin.robot import RobotModel
    from twin.sim import Simulation
    from twin.viz.calibration import CalibrationLog
    from twin.viz.recording import Recording

DEFAULT_WEB_PORT = 9090
DEFAULT_GRPC_PORT = 9876


@dataclass(frozen=True)
class RerunOptions:
    """Where a recording goes.

    Attributes:
        save: ``.rrd`` file to write, or None.
        spawn: Start the native viewer and stream to it.
        serve: Serve the web viewer and a gRPC server on 127.0.0.1 until Ctrl-C.
        web_port: Port of the web viewer (HTTP) when serving.
        grpc_port: Port of the gRPC server the web viewer reads from; also the native
            viewer's port when spawning.
    """

    save: Path | None = None
    spawn: bool = False
    serve: bool = False
    web_port: int = DEFAULT_WEB_PORT
    grpc_port: int = DEFAULT_GRPC_PORT

    def __post_init__(self) -> None:
        for name in ("web_port", "grpc_port"):
            port = getattr(self, name)
            if not 0 < port < 65536:
                raise ValueError(f"{name}: {port}, expected 1..65535")

    @property
    def enabled(self) -> bool:
        """Whether anything is to be recorded."""
        return self.save is not None or self.spawn or self.serve


def _port(text: str) -> int:
    """A TCP port number, for argparse (which reports a bad one and exits with code 2)."""
    try:
        port = int(text)
    except ValueError:
        port = 0
    if not 0 < port < 65536:
        raise argparse.ArgumentTypeError(f"found {text!r}, expected a TCP port in 1..65535")
    return port


def add_rerun_flags(parser: argparse.ArgumentParser) -> None:
    """Add ``--rerun-save``, ``--rerun-spawn``, ``--rerun-serve`` and their port options."""
    group = parser.add_argument_group("Rerun visualisation (see docs/rerun.md)")
    group.add_argument("--rerun-save", type=OutputFile, metavar="FILE.rrd",
                       help="write a Rerun recording; open it later with `rerun FILE.rrd`")
    group.add_argument("--rerun-spawn", action="store_true",
                       help="stream to the native Rerun viewer (needs a display; without one "
                       "the recording is saved to a file instead)")
    group.add_argument("--rerun-serve", action="store_true",
                       help="serve the web viewer on 127.0.0.1 (headless machines): prints the "
                       "URL and keeps serving until Ctrl-C")
    group.add_argument("--rerun-web-port", type=_port, default=DEFAULT_WEB_PORT, metavar="PORT",
                       help=f"web viewer port for --rerun-serve (default {DEFAULT_WEB_PORT})")
    group.add_argument("--rerun-grpc-port", type=_port, default=DEFAULT_GRPC_PORT, metavar="PORT",
                       help="gRPC port of the served or spawned viewer "
                       f"(default {DEFAULT_GRPC_PORT})")


def rerun_options(args: argparse.Namespace) -> RerunOptions:
    """The options the flags of :func:`add_rerun_flags` parsed to."""
    return RerunOptions(save=args.rerun_save, spawn=args.rerun_spawn, serve=args.rerun_serve,
                        web_port=args.rerun_web_port, grpc_port=args.rerun_grpc_port)


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
        from twin.viz.report import scene_markdown

        recording.log_scene({"nominal": sim.robot, "true": sim.true_robot}, sim.measurements,
                            sim.rig, cable_to="true")
        recording.log_report(scene_markdown(sim.robot, sim.measurements, sim.rig, sim.delta))
