"""A Robot Web Services client for what a capture needs (:mod:`twin.hardware.rws.protocol`):
the joint values of the robot, three RAPID symbols, the execution state, a virtual
controller's unit position, logout.

An adapter: ``requests`` (the extra ``cabletwin[hardware]``) is imported when a client is made.
RWS 1.0 authenticates with HTTP digest (``requests.auth.HTTPDigestAuth``), RWS 2.0 with basic
authentication over HTTPS, verified against a CA file or, on an explicit ``insecure``, not at
all. Both keep the controller's session cookie, so that one capture is one session. JSON is
asked for (``json=1``; ``Accept: application/hal+json;v=2.0``); ``payload="xhtml"`` reads the
default XHTML instead.

Credentials come from the caller (flags or the environment variables :data:`USER_VARIABLE`,
:data:`PASSWORD_VARIABLE`; ABB's factory account otherwise) and never appear in a message or a
file.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import numpy as np
from numpy.typing import NDArray

from twin.errors import InputError, TwinError
from twin.hardware.rws import protocol
from twin.hardware.rws.protocol import (
    AXES,
    FACTORY_PASSWORD,
    FACTORY_USER,
    PASSWORD_VARIABLE,
    USER_VARIABLE,
    PayloadError,
)

SCHEMES = {"rws": (1, "http", 80), "rws2": (2, "https", 443)}
"""URL scheme: RWS version, transport, default port."""
RETRY_S = 0.2
"""Pause between tries of a request that could not reach the controller, s."""


class ControllerError(TwinError):
    """The controller could not be reached, refused the request, or answered off the protocol."""


class RefusedError(ControllerError):
    """The controller answered a request with an error (HTTP 4xx/5xx)."""


class AuthenticationError(ControllerError, InputError):
    """The controller refused the credentials (a user mistake: exit code 2)."""

    def __init__(self, connection: RwsConnection) -> None:
        InputError.__init__(
            self, f"credentials that the controller at {connection.url} refused (HTTP 401) "
            f"for user {connection.user!r}", f"those of an RWS user, with --rws-user and "
            f"--rws-password or {USER_VARIABLE} and {PASSWORD_VARIABLE}",
            source="--robot-source")


@dataclass(frozen=True)
class RwsConnection:
    """How to reach one controller.

    Attributes:
        url: The controller's base URL (``http://HOST:PORT``, ``https://…`` for RWS 2.0).
        version: 1 (IRC5) or 2 (OmniCore).
        user: The RWS user.
        password: Its password (never shown).
        ca_file: RWS 2.0: the CA file the controller's certificate is checked against.
        insecure: RWS 2.0: do not check the certificate.
        timeout_s: Longest wait for one answer, s.
        retry_s: How long to keep trying a controller that cannot be reached, s.
        payload: ``json`` or ``xhtml``.
    """

    url: str
    version: int
    user: str = FACTORY_USER
    password: str = field(default=FACTORY_PASSWORD, repr=False)
    ca_file: Path | None = None
    insecure: bool = False
    timeout_s: float = 5.0
    retry_s: float = 5.0
    payload: str = "json"

    @classmethod
    def from_spec(cls, spec: str, *, user: str | None = None, password: str | None = None,
                  ca_file: Path | None = None, insecure: bool = False,
                  **options: Any) -> RwsConnection:
        """The connection a ``--robot-source`` URL names; credentials from the arguments, else
        the environment, else ABB's factory account.

        Raises:
            InputError: for a malformed URL, credentials inside it, or TLS flags that do not
                fit the version.
        """
        parts = urlsplit(spec)
        if parts.scheme not in SCHEMES or not parts.hostname or parts.path not in ("", "/") \
                or parts.query or parts.fragment:
            raise InputError(f"{spec!r}" if "@" not in spec else "a URL with credentials",
                             "rws://HOST[:PORT] (IRC5, RWS 1.0) or rws2://HOST[:PORT] "
                             "(OmniCore, RWS 2.0)", source="--robot-source")
        if parts.username is not None or parts.password is not None:
            raise InputError("credentials in the URL", f"--rws-user/--rws-password or "
                             f"{USER_VARIABLE}/{PASSWORD_VARIABLE}", source="--robot-source")
        try:
            port = parts.port
        except ValueError:
            raise InputError(f"port {parts.netloc.rsplit(':', 1)[-1]!r}", "a port in 1..65535",
                             source="--robot-source") from None
        version, transport, default_port = SCHEMES[parts.scheme]
        if version == 1 and (ca_file is not None or insecure):
            raise InputError("--ca-file or --insecure with rws://", "them with rws2:// only "
                             "(RWS 1.0 is plain HTTP)", source="command line")
        if version == 2 and (ca_file is None) == (not insecure):
            raise InputError("both --ca-file and --insecure" if insecure else "neither "
                             "--ca-file nor --insecure", "one: the CA file the controller's "
                             "certificate is checked against, or --insecure to skip the "
                             "check", source="command line")
        host = f"[{parts.hostname}]" if ":" in parts.hostname else parts.hostname
        return cls(f"{transport}://{host}:{port or default_port}", version,
                   user or os.environ.get(USER_VARIABLE) or FACTORY_USER,
                   password or os.environ.get(PASSWORD_VARIABLE) or FACTORY_PASSWORD,
                   ca_file, insecure, **options)


class RwsClient:
    """One session with a controller.

    Raises (every method):
        AuthenticationError: on HTTP 401.
        ControllerError: if the controller stays unreachable for ``retry_s``, or answers with
            an error or off the protocol.
    """

    def __init__(self, connection: RwsConnection) -> None:
        import requests
        from requests.auth import HTTPBasicAuth, HTTPDigestAuth

        self.connection = connection
        self.session = requests.Session()
        self.session.auth = (HTTPDigestAuth if connection.version == 1 else HTTPBasicAuth)(
            connection.user, connection.password)
        # Given with each request: a session's own setting gives way to REQUESTS_CA_BUNDLE.
        self.verify: str | bool = True
        if connection.version == 2:
            self.verify = str(connection.ca_file) if connection.ca_file else False
            if connection.insecure:
                import urllib3

                urllib3.disable_warnings(urllib3.exceptions.InsecureRequestWarning)
        accept = protocol.accept_type(connection.version, connection.payload)
        if accept:
            self.session.headers["Accept"] = accept

    def _request(self, verb: str, path: str, params: dict[str, str] | None = None,
                 data: dict[str, str] | None = None, *, retry: bool = True
                 ) -> tuple[bytes, str]:
        import requests

        query = dict(params or {})
        if self.connection.version == 1 and self.connection.payload == "json" and verb == "GET":
            query["json"] = "1"  # a common URL parameter; a POST answers with no body
        headers = {} if data is None else {"Content-Type":
                                           protocol.form_type(self.connection.version)}
        deadline = time.monotonic() + (self.connection.retry_s if retry else 0.0)
        while True:
            try:
                answer = self.session.request(verb, self.connection.url + path, params=query,
                                              data=data, headers=headers, verify=self.verify,
                                              timeout=self.connection.timeout_s)
                break
            except requests.exceptions.SSLError as exc:
                raise ControllerError(f"{self.connection.url}: the TLS handshake failed "
                                      f"({_reason(exc)}); give the controller's CA with "
                                      "--ca-file, or --insecure") from None
            except (requests.exceptions.ConnectionError, requests.exceptions.Timeout) as exc:
                if time.monotonic() >= deadline:
                    raise ControllerError(f"cannot reach the controller at "
                                          f"{self.connection.url} (is it on, the address "
                                          f"right, RWS enabled?): {_reason(exc)}") from None
                time.sleep(RETRY_S)
        content_type = answer.headers.get("Content-Type", "")
        if answer.status_code == 401:
            raise AuthenticationError(self.connection)
        if answer.status_code >= 400:
            status = protocol.parse_status(answer.content, content_type)
            raise RefusedError(f"{verb} {path}: the controller answered HTTP "
                               f"{answer.status_code}" + (f" ({status})" if status else ""))
        return answer.content, content_type

    def _state(self, path: str, state_type: str) -> protocol.State:
        body, content_type = self._request("GET", path)
        try:
            return protocol.find_state(body, content_type, state_type)
        except PayloadError as exc:
            raise ControllerError(f"GET {path}: {exc}") from None

    def axes_deg(self, unit: str = protocol.MECHUNIT) -> NDArray[np.float64]:
        """The unit's 12 jointtarget values (rax_1..rax_6, eax_a..eax_f), degrees."""
        path = protocol.jointtarget_path(unit)
        fields = self._state(path, protocol.JOINTTARGET_TYPE).fields
        try:
            return np.array([float(fields[axis]) for axis in AXES])
        except (KeyError, ValueError):
            raise ControllerError(f"GET {path}: a jointtarget without the numbers "
                                  f"{','.join(AXES)}") from None

    def symbol(self, task: str, module: str, symbol: str) -> str:
        """A RAPID symbol's value, as RAPID text (``3``, ``TRUE``)."""
        path = protocol.symbol_path(self.connection.version, task, module, symbol)
        fields = self._state(path, protocol.DATA_TYPE).fields
        if "value" not in fields:
            raise ControllerError(f"GET {path}: a rap-data item without a value")
        return fields["value"]

    def set_symbol(self, task: str, module: str, symbol: str, value: str) -> None:
        """Set a RAPID symbol's current value (RAPID text)."""
        version = self.connection.version
        self._request("POST", protocol.symbol_path(version, task, module, symbol),
                      protocol.set_symbol_query(version), {"value": value})

    def execution_state(self) -> str:
        """The RAPID execution state: ``running`` or ``stopped``."""
        state = self._state(protocol.EXECUTION_PATH, protocol.EXECUTION_TYPE)
        return state.fields.get("ctrlexecstate", "")

    def set_position(self, axes_deg: NDArray[np.float64],
                     unit: str = protocol.MECHUNIT) -> None:
        """Move a virtual controller's unit to joint values (rob_joint, ext_joint, degrees)."""
        path, params = protocol.position_path(self.connection.version, unit)
        values = [float(v) for v in axes_deg]
        self._request("POST", path, params, {"rob_joint": protocol.rapid_list(values[:6]),
                                             "ext_joint": protocol.rapid_list(values[6:])})

    def close(self) -> None:
        """Log out (the controller frees the session) and close the connection."""
        try:
            self._request("GET", protocol.LOGOUT_PATH, retry=False)
        except ControllerError:
            pass  # a controller gone away has no session to free
        finally:
            self.session.close()


def _reason(exc: Exception) -> str:
    """The innermost reason of a requests error, without the URL it repeats."""
    reason: BaseException = exc
    while reason.__context__ is not None and not isinstance(reason, OSError):
        reason = reason.__context__
    text = str(reason)
    text = text.rsplit("] ", 1)[-1] if "] " in text else text
    return text.rstrip("')\"").strip()
