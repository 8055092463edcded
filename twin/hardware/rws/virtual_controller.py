"""A virtual ABB controller on loopback: the Robot Web Services resources a capture uses
(:mod:`twin.hardware.rws.protocol`), the same URLs, authentication and payloads, with a robot
that runs the RAPID plan module of :mod:`twin.io.rapid_handshake`.

- **RWS 1.0** (IRC5): HTTP, digest authentication; XHTML, or JSON with ``json=1``.
  **RWS 2.0** (OmniCore): HTTPS with the given certificate, basic authentication; XHTML or HAL
  JSON as the ``Accept`` header asks, request bodies ``…;v=2.0`` (another is HTTP 415).
  A logged-in client gets the session cookies and may send them instead of credentials.
- **The program.** Once the module file exists (an operator loading it), the execution state
  turns ``running`` and the program runs as written: for each plan pose a joint move of
  ``move_s`` (the jointtarget reports the way there), the pose published to the virtual
  encoder's pose file (:func:`twin.hardware.robot_sources.sim.publish_pose`: pose K approached
  from pose K − 1, home for pose 1), then ``twin_pose``, ``twin_ready`` and a wait for
  ``twin_ack``. At the end: ``stopped``.
- **What it reports** is the motor side, as a controller does: the commanded joint values once
  the move is done (to 1e-6 deg). The link side — the twin's true robot with its transmission
  error and backlash of the approach side — is what the virtual encoder's cable measures.
- **Jogging.** Without a program, ``POST …mechunit-position`` (a virtual controller's own
  resource) moves the unit as an operator's jog would.
- **Faults** for tests: ``refuse_pose`` K stops the execution before pose K (as a controller
  refusing a pose, e.g. outside its joint limits; so does any pose outside the robot's limits);
  ``creep_pose`` K keeps joint 1 creeping at pose K (motion that never stops).

Standard library only (``http.server.ThreadingHTTPServer``, ``ssl``).
"""

from __future__ import annotations

import math
import ssl
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit

import numpy as np
from numpy.typing import NDArray

from twin.errors import InputError
from twin.hardware.robot_sources.sim import publish_pose
from twin.hardware.rws import protocol
from twin.hardware.rws.auth import Authenticator, session_cookies
from twin.io.rapid_handshake import (
    ACK_SYMBOL,
    POSE_SYMBOL,
    READY_SYMBOL,
    TASK,
    axes_deg,
    joints_deg,
    read_handshake_module,
)
from twin.units import deg_to_rad, rad_to_deg
from twin.waiting import serve_until_stopped

CREEP_DEG_S = 0.05
"""How fast joint 1 creeps at the creeping pose, deg/s."""
SYMBOL_NOT_FOUND = -1073445879
"""The controller's return code of a RAPID symbol that does not exist."""


@dataclass(frozen=True)
class ControllerSettings:
    """What the virtual controller runs.

    Attributes:
        n_joints: Joints of the arm.
        lower_deg, upper_deg: Its joint limits, degrees, shape (n,).
        module: The RAPID plan module's file (run once it exists).
        pose_file: Where the pose is published for the virtual encoder.
        move_s: Duration of each joint move, s.
        refuse_pose, creep_pose: Fault injection (0: none).
    """

    n_joints: int
    lower_deg: tuple[float, ...]
    upper_deg: tuple[float, ...]
    module: Path | None
    pose_file: Path
    move_s: float = 0.1
    refuse_pose: int = 0
    creep_pose: int = 0


class Robot:
    """The mechanical unit and the RAPID task: joint values over time, symbols, execution."""

    def __init__(self, settings: ControllerSettings) -> None:
        self.settings = settings
        self.lock = threading.Condition()
        self.symbols: dict[str, str] = {}
        self.module = ""
        self.execution = "stopped"
        home = axes_deg(np.zeros(settings.n_joints))
        self._from, self._to, self._start, self._creep_since = home, home, 0.0, math.inf
        self._jogs = 0

    def axes_now(self) -> NDArray[np.float64]:
        """The 12 jointtarget values the unit reports now, degrees."""
        with self.lock:
            elapsed = time.monotonic() - self._start
            share = min(1.0, elapsed / self.settings.move_s)
            axes = self._from + share * (self._to - self._from)
            axes[0] += CREEP_DEG_S * max(0.0, time.monotonic() - self._creep_since)
        return np.round(axes, 6)

    def _move(self, target_axes: NDArray[np.float64]) -> None:
        with self.lock:
            self._from, self._to = self.axes_now(), target_axes
            self._start, self._creep_since = time.monotonic(), math.inf
        time.sleep(self.settings.move_s)

    def jog(self, target_axes: NDArray[np.float64]) -> None:
        """Move as a jog would, and tell the encoder."""
        before = joints_deg(self.axes_now(), self.settings.n_joints)
        self._move(target_axes)
        self._jogs += 1
        publish_pose(self.settings.pose_file, self._jogs,
                     deg_to_rad(joints_deg(target_axes, self.settings.n_joints)),
                     deg_to_rad(before))

    def _outside(self, q_deg: NDArray[np.float64]) -> bool:
        return bool(np.any(q_deg < np.array(self.settings.lower_deg) - 1e-9)
                    or np.any(q_deg > np.array(self.settings.upper_deg) + 1e-9))

    def run_program(self, stop: threading.Event) -> None:
        """Wait for the module file, then run the plan module (see the module docstring)."""
        path = self.settings.module
        if path is None:
            return
        while not path.exists():
            if stop.wait(0.05):
                return
        plan = read_handshake_module(path, self.settings.n_joints)
        with self.lock:
            self.module = plan.name
            self.symbols = {POSE_SYMBOL: "0", READY_SYMBOL: "FALSE", ACK_SYMBOL: "0"}
            self.execution = "running"
        previous = np.zeros(self.settings.n_joints)
        for k, q_rad in enumerate(plan.q_rad, start=1):
            q_deg = rad_to_deg(q_rad)
            if k == self.settings.refuse_pose or self._outside(q_deg):
                with self.lock:
                    self.execution = "stopped"
                return
            self._move(axes_deg(q_deg))
            publish_pose(self.settings.pose_file, k, q_rad, previous)
            with self.lock:
                if k == self.settings.creep_pose:
                    self._creep_since = time.monotonic()
                self.symbols[POSE_SYMBOL] = str(k)
                self.symbols[READY_SYMBOL] = "TRUE"
                while self.symbols[ACK_SYMBOL] != str(k):
                    if stop.is_set():
                        return
                    self.lock.wait(0.05)
                self.symbols[READY_SYMBOL] = "FALSE"
            previous = q_rad
        with self.lock:
            self.execution = "stopped"

    def set_symbol(self, name: str, value: str) -> bool:
        """Set a symbol of the loaded module; False if there is none of that name."""
        with self.lock:
            if name not in self.symbols:
                return False
            self.symbols[name] = value.strip()
            self.lock.notify_all()
        return True


class AnswerError(Exception):
    """An HTTP answer other than 200 with a state, raised inside a route."""

    def __init__(self, status: int, code: int = 0, message: str = "") -> None:
        super().__init__(message)
        self.status, self.code, self.message = status, code, message


def _symbol_name(robot: Robot, version: int, path: str) -> str:
    """The symbol a data path names in the loaded module.

    Raises:
        AnswerError: 400 if the module is not loaded or has no such symbol.
    """
    prefix = f"/rw/rapid/symbol/data/RAPID/{TASK}/" if version == 1 \
        else f"/rw/rapid/symbol/RAPID/{TASK}/"
    rest = path[len(prefix):] if path.startswith(prefix) else ""
    if version == 2:
        rest = rest[:-len("/data")] if rest.endswith("/data") else ""
    module, _, name = rest.partition("/")
    with robot.lock:
        known = module == robot.module and name in robot.symbols
    if not known:
        raise AnswerError(400, SYMBOL_NOT_FOUND, f"symbol RAPID/{TASK}/{rest} not found")
    return name


class Handler(BaseHTTPRequestHandler):
    """One request to the virtual controller (the server holds the robot and the settings)."""

    server: Server
    protocol_version = "HTTP/1.1"
    # The headers and the body leave in two writes: with Nagle's algorithm the body waited for
    # the client's delayed ACK of the headers, some 40 ms on every answer (9 a pose).
    disable_nagle_algorithm = True

    def log_message(self, format: str, *args: Any) -> None:
        """Quiet: the request log is :attr:`Server.requests`."""

    def _payload(self, query: dict[str, str]) -> str:
        if self.server.version == 1:
            return "json" if query.get("json") == "1" else "xhtml"
        return "json" if "hal+json" in self.headers.get("Accept", "") else "xhtml"

    def _send(self, status: int, body: bytes = b"", content_type: str = "",
              cookies: list[str] | None = None, extra: dict[str, str] | None = None) -> None:
        self.send_response(status)
        if content_type:
            self.send_header("Content-Type", content_type)
        for cookie in cookies or []:
            self.send_header("Set-Cookie", cookie)
        for key, value in (extra or {}).items():
            self.send_header(key, value)
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def _handle(self, method: str) -> None:
        parts = urlsplit(self.path)
        query = {k: v[-1] for k, v in parse_qs(parts.query).items()}
        # json=1 (and debug=1) are common URL parameters of every RWS 1.0 resource.
        route_query = {k: v for k, v in query.items() if k not in ("json", "debug")}
        length = int(self.headers.get("Content-Length") or 0)
        raw = self.rfile.read(length) if length else b""
        if len(raw) < length:
            # The client went away between its headers and the end of its form (a capture
            # killed mid-request; its HTTP library sends the two apart): a request that did not
            # arrive whole is not one, for a controller as for any HTTP server.
            self.close_connection = True
            return
        form = {k: v[-1] for k, v in parse_qs(raw.decode("utf-8", errors="replace")).items()}
        self.server.log(method, parts.path, query, self.headers, form)
        ok, token = self.server.auth.check(self.headers.get("Authorization"),
                                           self.headers.get("Cookie"), method, self.path)
        if not ok:
            self._send(401, extra={"WWW-Authenticate": self.server.auth.challenge()})
            return
        cookies = session_cookies(token) if token else None
        payload = self._payload(query)
        try:
            state = self.server.route(method, parts.path, route_query, form, self.headers)
        except AnswerError as answer:
            if answer.code:
                error, content_type = protocol.render_status(self.server.version, payload,
                                                             answer.code, answer.message)
                self._send(answer.status, error, content_type, cookies)
            else:
                self._send(answer.status, cookies=cookies)
            return
        base = f"{self.server.scheme}://{self.headers.get('Host', '')}{parts.path}/"
        answer_body, content_type = protocol.render_state(self.server.version, payload, base,
                                                          state)
        self._send(200, answer_body, content_type, cookies)

    def do_GET(self) -> None:
        """A GET."""
        self._handle("GET")

    def do_POST(self) -> None:
        """A POST."""
        self._handle("POST")


class Server(ThreadingHTTPServer):
    """The virtual controller's HTTP(S) server.

    Args:
        robot: The unit and task it serves.
        version: 1 or 2.
        user, password: The one account.
        port: The TCP port on 127.0.0.1 (0: any free one).
        tls: RWS 2.0: the server's certificate chain and key files.
    """

    daemon_threads = True

    def __init__(self, robot: Robot, version: int, user: str, password: str, port: int = 0,
                 tls: tuple[Path, Path] | None = None) -> None:
        super().__init__(("127.0.0.1", port), Handler)
        self.robot, self.version = robot, version
        self.auth = Authenticator(version, user, password)
        self.requests: list[dict[str, Any]] = []
        self.scheme = "https" if version == 2 else "http"
        if version == 2:
            if tls is None:
                raise InputError("no certificate", "--cert and --key for RWS 2.0 (HTTPS)",
                                 source="command line")
            context = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
            context.load_cert_chain(str(tls[0]), str(tls[1]))
            self.socket = context.wrap_socket(self.socket, server_side=True)

    @property
    def url(self) -> str:
        """The ``--robot-source`` URL of this controller."""
        return f"rws{'2' if self.version == 2 else ''}://127.0.0.1:{self.server_address[1]}"

    def log(self, method: str, path: str, query: dict[str, str], headers: Any,
            form: dict[str, str]) -> None:
        """Record a request as it came (no credentials: only the scheme of the header)."""
        self.requests.append({
            "method": method, "path": path, "query": query,
            "auth": (headers.get("Authorization") or "").partition(" ")[0],
            "content_type": headers.get("Content-Type"), "accept": headers.get("Accept"),
            "form": sorted(form)})

    def route(self, method: str, path: str, query: dict[str, str], form: dict[str, str],
              headers: Any) -> protocol.State:
        """The state a request reads, after doing what it asks.

        Raises:
            AnswerError: for an answer without a state (204, 4xx).
        """
        version, robot = self.version, self.robot
        if method == "POST" and version == 2 and headers.get("Content-Type") != protocol.FORM_V2:
            raise AnswerError(415, -1073445866, "unsupported media type: expected "
                         f"{protocol.FORM_V2}")
        if method == "GET" and path == protocol.jointtarget_path():
            fields = dict(zip(protocol.AXES, (f"{v:.6f}" for v in robot.axes_now()),
                              strict=True))
            return protocol.State(protocol.JOINTTARGET_TYPE, protocol.MECHUNIT, fields)
        if method == "GET" and path == protocol.EXECUTION_PATH:
            with robot.lock:
                execution = robot.execution
            return protocol.State(protocol.EXECUTION_TYPE, "execution",
                                  {"ctrlexecstate": execution, "cycle": "once"})
        if method == "GET" and path == protocol.LOGOUT_PATH:
            self.auth.logout(headers.get("Cookie"))
            raise AnswerError(204)
        if path.startswith("/rw/rapid/symbol/"):
            return self._symbol(method, path, query, form)
        if method == "POST" and (path, query) == protocol.position_path(version):
            self._jog(form)
            raise AnswerError(204)
        raise AnswerError(404, -1073445871, f"resource {method} {path} not found")

    def _symbol(self, method: str, path: str, query: dict[str, str],
                form: dict[str, str]) -> protocol.State:
        name = _symbol_name(self.robot, self.version, path)
        if method == "POST":
            if query != protocol.set_symbol_query(self.version) or "value" not in form:
                raise AnswerError(400, -1073445865, "bad request: expected "
                             f"{protocol.set_symbol_query(self.version)} and value=")
            self.robot.set_symbol(name, form["value"])
            raise AnswerError(204)
        with self.robot.lock:
            value = self.robot.symbols[name]
        return protocol.State(protocol.DATA_TYPE, f"RAPID/{TASK}/{self.robot.module}/{name}",
                              {"value": value})

    def _jog(self, form: dict[str, str]) -> None:
        try:
            values = [float(v) for key in ("rob_joint", "ext_joint")
                      for v in form[key].strip("[]").split(",")]
        except (KeyError, ValueError):
            values = []
        if len(values) != 12:
            raise AnswerError(400, -1073445865, "bad request: expected rob_joint=[6 values] and "
                         "ext_joint=[6 values]")
        self.robot.jog(np.array(values))


class Running:
    """A virtual controller serving in threads of this process (:func:`start`)."""

    def __init__(self, server: Server, stop: threading.Event) -> None:
        self.server, self._stop = server, stop

    @property
    def url(self) -> str:
        """The ``--robot-source`` URL."""
        return self.server.url

    def stop(self) -> None:
        """Stop the program and the server."""
        self._stop.set()
        self.server.shutdown()
        self.server.server_close()


def start(robot: Robot, version: int, user: str, password: str, *, port: int = 0,
          tls: tuple[Path, Path] | None = None) -> Running:
    """Start the virtual controller's program and server in threads."""
    stop = threading.Event()
    server = Server(robot, version, user, password, port, tls)
    threading.Thread(target=robot.run_program, args=(stop,), daemon=True).start()
    threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05},
                     daemon=True).start()
    return Running(server, stop)


def serve(robot: Robot, version: int, user: str, password: str, *, port: int = 0,
          tls: tuple[Path, Path] | None = None,
          announce: Callable[[str], None] | None = None) -> None:
    """Serve the virtual controller until the process is stopped.

    Args:
        announce: Called with the ``--robot-source`` URL once the server listens.
    """
    running = start(robot, version, user, password, port=port, tls=tls)
    if announce is not None:
        announce(running.url)
    try:
        serve_until_stopped()
    finally:
        running.stop()
