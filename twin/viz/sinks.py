"""Where a recording's data goes: a ``.rrd`` file, the native viewer, a served web viewer.

Data is never dropped: when the native viewer cannot start (no display, no ``rerun``
executable, or it does not come up) we say so on stderr and save to a file instead. Files are
written beside their final name and renamed into place when the recording closes
(:mod:`twin.io.atomic`), so a ``.rrd`` is either complete or absent. Viewer processes we start
listen on 127.0.0.1 only and are stopped when the recording closes.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from types import FrameType
from typing import Any, NamedTuple
from urllib.parse import quote

import rerun as rr

from twin.io.atomic import commit, temporary_beside
from twin.viz.options import RerunOptions
from twin.waiting import serve_until_stopped

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
        # Awake every WAKE_S: a SIGTERM taken by one of Rerun's threads runs its handler only
        # when this thread next runs Python (an hour's sleep kept serving for up to an hour).
        serve_until_stopped()
    except KeyboardInterrupt:
        say("stopped serving")
    finally:
        signal.signal(signal.SIGTERM, previous)

class Opened(NamedTuple):
    """Where an open recording goes, beyond the viewers it streams to."""

    path: Path | None
    """The ``.rrd`` file being written (its final name), or None."""
    url: str | None
    """The web viewer's address when serving, or None."""


@contextmanager
def open_sinks(stream: rr.RecordingStream, options: RerunOptions, name: str,
               fallback_dir: Path | None = None) -> Iterator[Opened]:
    """Start what ``options`` ask for and point ``stream`` at it; on leaving the block, flush,
    keep serving until Ctrl-C if serving, stop the viewer processes and put the file in place
    (also when the block is left by an exception or Ctrl-C: what was recorded is kept).

    Args:
        stream: The recording stream, not yet connected.
        options: The sinks.
        name: The command (``"calibrate"``…): the fallback file's name.
        fallback_dir: Folder of the fallback file (default: the current folder).
    """
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
        temporary = temporary_beside(path)
        sinks.append(rr.FileSink(temporary))
    stream.set_sinks(*sinks)
    try:
        yield Opened(path, url)
    finally:
        stream.flush()
        if url is not None:
            wait_for_interrupt(url)
        stream.disconnect()
        if server is not None:
            stop_process(server)
        if path is not None and temporary is not None:
            commit(temporary, path)
            say(f"saved {path}")
