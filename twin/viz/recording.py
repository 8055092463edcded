"""A Rerun recording on the sinks the user asked for: a file, the native viewer, a web viewer.

Data is never dropped: when the native viewer cannot start (no display, no ``rerun``
executable, or it does not come up) we say so on stderr and save to a file instead. Files are
written beside their final name and renamed into place when the recording closes, so a
``.rrd`` is either complete or absent.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from types import FrameType
from typing import Any
from urllib.parse import quote

import numpy as np
import rerun as rr
from numpy.typing import NDArray

from twin.calibration import CalibrationResult
from twin.dataset import Measurements
from twin.io.atomic import fsync_directory
from twin.rig import Rig
from twin.robot import RobotModel
from twin.viz import entities
from twin.viz.blueprint import scene_blueprint
from twin.viz.calibration import CalibrationLog, log_calibration
from twin.viz.cli import RerunOptions
from twin.viz.scene import log_scene, robot_color
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

    def start_calibration(
        self,
        methods: Sequence[str],
        robot: RobotModel,
        rig: Rig,
        measurements: Measurements,
        *,
        truth_delta: NDArray[np.float64] | None = None,
    ) -> CalibrationLog:
        """Log a calibration's setup now and return the log its methods are added to as they
        finish (see :class:`twin.viz.calibration.CalibrationLog`)."""
        return CalibrationLog(Writer(self.stream), methods, robot, rig, measurements,
                              truth_delta)

    def log_scene(
        self,
        robots: Mapping[str, RobotModel],
        measurements: Measurements,
        rig: Rig,
        *,
        cable_to: str,
        times: Mapping[str, int] | None = None,
    ) -> None:
        """Robots in every pose and what was measured (see :func:`twin.viz.scene.log_scene`)."""
        self.stream.send_blueprint(scene_blueprint())
        log_scene(Writer(self.stream, times), robots, measurements, rig, cable_to)

    def log_histories(self, histories_mm: Mapping[str, Sequence[float]], trial: str) -> None:
        """One study trial's validation RMSE per iteration [mm] for each method, on the
        ``iteration`` timeline under ``convergence/<method>/trials/<trial>``, so the curves of
        all trials lie side by side in each method's plot."""
        writer = Writer(self.stream)
        for order, (method, values) in enumerate(histories_mm.items()):
            if not len(values):
                continue
            path = entities.trial_convergence(method, trial)
            writer.once(path, rr.SeriesLines(colors=robot_color(method, order),
                                             names=f"{method} {trial}"))
            writer.series(path, entities.ITERATION_TIMELINE, np.arange(len(values)),
                          rr.Scalars.columns(scalars=np.asarray(values, dtype=np.float64)))

    def log_report(self, markdown: str, path: str = entities.REPORT,
                   times: Mapping[str, int] | None = None) -> None:
        """A markdown document (the run's report by default)."""
        Writer(self.stream, times).once(path, rr.TextDocument(markdown,
                                                              media_type=rr.MediaType.MARKDOWN))


def port_is_free(port: int) -> bool:
    """Whether nothing listens on 127.0.0.1:``port`` yet."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        # As servers do: a port whose old connections linger in TIME_WAIT is free.
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((LOOPBACK, port))
        except OSError:
            return False
    return True


def grpc_uri(port: int) -> str:
    """The address an SDK or a viewer uses to reach a gRPC server on 127.0.0.1:``port``."""
    return f"rerun+http://{LOOPBACK}:{port}/proxy"


def spawn_viewer(stream: rr.RecordingStream, port: int) -> str | None:
    """Start the native viewer listening on ``port``; None, or why it could not start.

    A viewer already listening on the port (left open from an earlier run, or forwarded from a
    desktop) is used as it is, as ``rerun.spawn`` itself does.
    """
    if not port_is_free(port):
        say(f"port {port} is taken: streaming to the viewer already listening there")
        return None
    reason = why_no_viewer()
    if reason is not None:
        return reason
    try:
        rr.spawn(port=port, connect=False, executable_path=rerun_executable(), recording=stream)
    except RuntimeError as exc:
        return f"the viewer did not start ({str(exc).splitlines()[0]})"
    if not port_accepts(port, VIEWER_START_SECONDS):
        return f"the viewer did not listen on port {port}"
    return None


def serve_web_viewer(web_port: int, port: int) -> subprocess.Popen[bytes] | str:
    """Start ``rerun --serve-web`` on 127.0.0.1 only: the server process, or why it failed.

    The SDK's own web server listens on every interface; the ``rerun`` executable can be told
    to bind the web viewer and its gRPC server to the loopback address, so it is used instead.
    """
    executable = rerun_executable()
    if executable is None:
        return "no `rerun` executable (pip install rerun-sdk)"
    busy = [str(p) for p in (web_port, port) if not port_is_free(p)]
    if busy:
        return (f"port {' and '.join(busy)} in use (choose others with --rerun-web-port, "
                "--rerun-grpc-port)")
    process = subprocess.Popen(
        [executable, "--serve-web", "--bind", LOOPBACK, "--web-viewer-port", str(web_port),
         "--port", str(port)],
        stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        # `rerun` may be a wrapper script around the real binary: give the pair a process
        # group of their own so that stopping it stops both.
        start_new_session=True,
    )
    if all(port_accepts(p, VIEWER_START_SECONDS) for p in (port, web_port)):
        return process
    stop_process(process)
    return f"the web viewer did not listen on ports {web_port} and {port}"


def stop_process(process: subprocess.Popen[bytes]) -> None:
    """Terminate a server process we started (and its process group), and reap it."""
    os.killpg(process.pid, signal.SIGTERM)
    try:
        process.wait(timeout=10)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait()


def _raise_interrupt(signum: int, frame: FrameType | None) -> None:
    raise KeyboardInterrupt


def wait_for_interrupt(url: str) -> None:
    """Keep serving until Ctrl-C (or SIGTERM, so that a supervisor stops us cleanly)."""
    say(f"serving the web viewer at {url} — press Ctrl-C to stop")
    previous = signal.signal(signal.SIGTERM, _raise_interrupt)
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        say("stopped serving")
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextmanager
def open_recording(
    options: RerunOptions, name: str, *, fallback_dir: Path | None = None
) -> Iterator[Recording]:
    """Open a recording on every sink the options ask for; close it on leaving the block.

    With ``options.serve`` the web viewer's URL is printed on opening, and leaving the block
    keeps serving until Ctrl-C. A viewer that cannot start is replaced by a file.

    Args:
        options: The sinks.
        name: The command (``"calibrate"``…): the recording's name and the fallback file's.
        fallback_dir: Folder of the fallback file (default: the current folder).
    """
    stream = rr.RecordingStream(APPLICATION_ID)
    sinks: list[Any] = []
    path = options.save
    failed = []
    server = None
    url = None
    if options.serve:
        started = serve_web_viewer(options.web_port, options.grpc_port)
        if isinstance(started, str):
            failed.append(f"cannot serve the web viewer: {started}")
        else:
            server = started
            sinks.append(rr.GrpcSink(grpc_uri(options.grpc_port)))
            url = web_viewer_url(options.web_port, grpc_uri(options.grpc_port))
            say(f"web viewer at {url} (native viewer: `rerun {grpc_uri(options.grpc_port)}`)")
    if options.spawn:
        # When serving, the web viewer's server already has grpc_port: take the next one.
        port = options.grpc_port + (server is not None)
        reason = spawn_viewer(stream, port)
        if reason is None:
            sinks.append(rr.GrpcSink(grpc_uri(port)))
        else:
            failed.append(f"cannot spawn the viewer: {reason}")
    for message in failed:
        say(message)
    if failed and path is None:
        path = fallback_path(name, fallback_dir)
        say(f"saving the recording to {path} instead; open it with `rerun {path}`")
    temporary = None
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        temporary = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        sinks.append(rr.FileSink(temporary))
    stream.set_sinks(*sinks)
    stream.send_recording_name(name)
    try:
        yield Recording(stream, path, url)
    finally:
        stream.flush()
        if url is not None:
            wait_for_interrupt(url)
        stream.disconnect()
        if server is not None:
            stop_process(server)
        if path is not None and temporary is not None:
            with temporary.open("rb+") as handle:
                os.fsync(handle.fileno())
            os.replace(temporary, path)
            fsync_directory(path.parent)
            say(f"saved {path}")
