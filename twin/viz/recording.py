"""A Rerun recording on the sinks the user asked for: a file, the native viewer, a web viewer.

Data is never dropped: when the native viewer cannot start (no display, no ``rerun``
executable, or it does not come up) we say so on stderr and save to a file instead. Files are
written beside their final name and renamed into place when the recording closes, so a
``.rrd`` is either complete or absent.
"""

from __future__ import annotations

import os
import shutil
import socket
import sys
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import Any
from urllib.parse import quote

import numpy as np
import rerun as rr
from numpy.typing import ArrayLike, NDArray

from twin.cable import Measurements
from twin.calibration import CalibrationResult
from twin.io.atomic import fsync_directory
from twin.robot import RobotModel
from twin.viz import entities
from twin.viz.blueprint import scene_blueprint
from twin.viz.calibration import log_calibration
from twin.viz.cli import RerunOptions
from twin.viz.scene import log_scene
from twin.viz.writer import Writer

APPLICATION_ID = "twin"
LOOPBACK = "127.0.0.1"
VIEWER_START_SECONDS = 10.0
"""How long a spawned viewer may take to accept connections before we fall back to a file."""


def say(message: str) -> None:
    """A status line on stderr (stdout carries the command's own output)."""
    print(f"twin: rerun: {message}", file=sys.stderr, flush=True)


def rerun_executable() -> str | None:
    """The ``rerun`` viewer executable: beside this Python (the venv's), else on PATH."""
    beside = Path(sys.executable).with_name("rerun")
    if beside.is_file() and os.access(beside, os.X_OK):
        return str(beside)
    return shutil.which("rerun")


def why_no_viewer() -> str | None:
    """Why the native viewer cannot open a window here, or None if it may."""
    if sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    ):
        return "no display (neither DISPLAY nor WAYLAND_DISPLAY is set)"
    if rerun_executable() is None:
        return "no `rerun` viewer executable (pip install rerun-sdk)"
    return None


def port_accepts(port: int, timeout_s: float) -> bool:
    """Whether something accepts TCP connections on 127.0.0.1:``port`` within the timeout."""
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            with socket.create_connection((LOOPBACK, port), timeout=0.5):
                return True
        except OSError:
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.2)


def fallback_path(name: str, folder: Path | None) -> Path:
    """``twin-<name>-<UTC timestamp>.rrd`` in ``folder`` (default: the current folder)."""
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    return (folder or Path.cwd()) / f"twin-{name}-{stamp}.rrd"


def web_viewer_url(web_port: int, grpc_uri: str) -> str:
    """The address of the served web viewer, connected to the gRPC server at ``grpc_uri``."""
    return f"http://{LOOPBACK}:{web_port}/?url={quote(grpc_uri, safe='')}"


class Recording:
    """One open recording. Log through its methods; :func:`open_recording` closes it.

    Attributes:
        stream: The underlying ``rerun.RecordingStream``, for anything else.
        path: The ``.rrd`` file being written (final name), or None.
        url: The web viewer's address when serving, or None.
    """

    def __init__(self, stream: rr.RecordingStream, path: Path | None, url: str | None):
        self.stream = stream
        self.path = path
        self.url = url

    def log_calibration(
        self,
        results: Mapping[str, CalibrationResult] | CalibrationResult,
        measurements: Measurements,
        *,
        truth_delta: NDArray[np.float64] | None = None,
        times: Mapping[str, int] | None = None,
    ) -> None:
        """Scene, residuals, convergence, parameters and report of a calibration run.

        Args:
            results: Results by method name (or a single result).
            measurements: Every measured pose (train and validation).
            truth_delta: True D-H errors, shape (4, n), m and rad, if known.
                times: Extra sequence timelines stamped on every row, e.g. ``{"case": k}``.
        """
        if isinstance(results, CalibrationResult):
            results = {results.method: results}
        log_calibration(Writer(self.stream, times), results, measurements, truth_delta)

    def log_scene(
        self,
        robots: Mapping[str, RobotModel],
        measurements: Measurements,
        port_m: ArrayLike,
        *,
        cable_to: str,
        times: Mapping[str, int] | None = None,
    ) -> None:
        """Robots in every pose, the port and the cable (see :func:`twin.viz.scene.log_scene`)."""
        self.stream.send_blueprint(scene_blueprint())
        log_scene(Writer(self.stream, times), robots, measurements, port_m, cable_to)

    def log_report(self, markdown: str, path: str = entities.REPORT,
                   times: Mapping[str, int] | None = None) -> None:
        """A markdown document (the run's report by default)."""
        Writer(self.stream, times).once(path, rr.TextDocument(markdown,
                                                              media_type=rr.MediaType.MARKDOWN))


def _viewer_sink(stream: rr.RecordingStream, port: int) -> rr.GrpcSink | None:
    """Spawn the native viewer on ``port`` and return a sink to it, or None (and say why)."""
    reason = why_no_viewer()
    if reason is None:
        try:
            rr.spawn(port=port, connect=False, executable_path=rerun_executable(),
                     recording=stream)
        except RuntimeError as exc:
            reason = f"the viewer did not start ({str(exc).splitlines()[0]})"
        else:
            if not port_accepts(port, VIEWER_START_SECONDS):
                reason = f"the viewer did not listen on port {port}"
    if reason is not None:
        say(f"cannot spawn the viewer: {reason}")
        return None
    return rr.GrpcSink(f"rerun+http://{LOOPBACK}:{port}/proxy")


def _wait_for_interrupt(url: str) -> None:
    say(f"serving the web viewer at {url} — press Ctrl-C to stop")
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        say("stopped serving")


@contextmanager
def open_recording(
    options: RerunOptions, name: str, *, fallback_dir: Path | None = None
) -> Iterator[Recording]:
    """Open a recording on every sink the options ask for; close it on leaving the block.

    With ``options.serve`` the web viewer's URL is printed on opening, and leaving the block
    keeps serving until Ctrl-C. A spawned viewer that cannot start is replaced by a file.

    Args:
        options: The sinks.
        name: The command (``"calibrate"``…): the recording's name and the fallback file's.
        fallback_dir: Folder of the fallback file (default: the current folder).
    """
    stream = rr.RecordingStream(APPLICATION_ID, send_properties=True)
    sinks: list[Any] = []
    path = options.save
    if options.spawn:
        # The served gRPC server already takes grpc_port; the spawned viewer takes the next one.
        viewer = _viewer_sink(stream, options.grpc_port + options.serve)
        if viewer is not None:
            sinks.append(viewer)
        elif path is None:
            path = fallback_path(name, fallback_dir)
            say(f"saving the recording to {path} instead; open it with `rerun {path}`")
    temporary = None
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        temporary = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        sinks.append(rr.FileSink(temporary))
    url = None
    if options.serve:
        server = rr.GrpcServerSink(LOOPBACK, options.grpc_port)
        sinks.append(server)
        rr.serve_web_viewer(web_port=options.web_port, open_browser=False, connect_to=server.uri)
        url = web_viewer_url(options.web_port, server.uri)
        say(f"web viewer at {url} (native viewer: `rerun --connect {server.uri}`)")
    stream.set_sinks(*sinks)
    stream.send_recording_name(name)
    recording = Recording(stream, path, url)
    try:
        yield recording
    finally:
        stream.flush()
        if url is not None:
            _wait_for_interrupt(url)
        stream.disconnect()
        if path is not None and temporary is not None:
            with temporary.open("rb+") as handle:
                os.fsync(handle.fileno())
            os.replace(temporary, path)
            fsync_directory(path.parent)
            say(f"saved {path}")
