"""The part of ABB Robot Web Services that a capture uses, as the documentation states it: the
resources, their parameters, their payloads, for RWS 1.0 (IRC5, RobotWare 6: HTTP, digest
authentication) and RWS 2.0 (OmniCore, RobotWare 7: HTTPS, basic authentication).

Sources: ABB, *Application manual — Robot Web Services*, 3HAC050973-001 (RWS 1.0, Revision M:
the pages "Get Joint target", "Get symbol data", "Update RAPID variable current value", "Get
RAPID Execution state", "Set Mechanical Unit", "Logout" and the common URL parameter
``json=1``); for RWS 2.0 the same resources under their 2.0 paths with the versioned media types
(``Accept: application/hal+json;v=2.0`` or ``application/xhtml+xml;v=2.0``, request bodies
``application/x-www-form-urlencoded;v=2.0``), as ROS-Industrial's abb_librws (``v2_0``) and
controllers' answers show them.

================================ ===== =============================================================
what                             verb  path (1.0 | 2.0)
================================ ===== =============================================================
joint values of a mechanical     GET   /rw/motionsystem/mechunits/{unit}/jointtarget (both)
unit (``ms-jointtarget``)
a RAPID symbol's value           GET   /rw/rapid/symbol/data/RAPID/{task}/{module}/{symbol} |
(``rap-data``)                         /rw/rapid/symbol/RAPID/{task}/{module}/{symbol}/data
set it (body ``value=…``)        POST  the same with ``?action=set`` | ``?mastership=implicit``
RAPID execution state            GET   /rw/rapid/execution (both)
(``rap-execution``: ctrlexecstate running | stopped)
move a virtual controller's unit POST  /rw/motionsystem/mechunits/{unit}?action=mechunit-position |
(body ``rob_joint=[…]&ext_joint=[…]``) /rw/motionsystem/mechunits/{unit}/position
end the session                  GET   /logout (both)
================================ ===== =============================================================

Payloads. XHTML: ``<li class="{type}" title="{title}">`` holding ``<span class="{field}">value
</span>``. JSON, RWS 1.0 (``?json=1``): ``{"_embedded": {"_state": [{"_type": type, "_title":
title, field: value, …}]}}``; RWS 2.0 (HAL): ``{"state": [{"_type": …, "_title": …, …}]}``.
Values are text in both (``"10"``, ``"TRUE"``). Errors carry a status code and message: JSON
``{"status": {"code": …, "msg": …}}`` (1.0 inside ``_embedded``), XHTML ``<div
class="status"><span class="code">…</span><span class="msg">…</span></div>``.
"""

from __future__ import annotations

import html
import json
import xml.etree.ElementTree as ElementTree
from typing import NamedTuple

from twin.errors import TwinError

VERSIONS = (1, 2)
USER_VARIABLE, PASSWORD_VARIABLE = "TWIN_RWS_USER", "TWIN_RWS_PASSWORD"
"""The environment variables a controller's user and password are read from."""
FACTORY_USER, FACTORY_PASSWORD = "Default User", "robotics"
"""ABB's factory account (RobotWare 6 and 7)."""
MECHUNIT = "ROB_1"
"""The robot's mechanical unit."""
JOINTTARGET_TYPE, DATA_TYPE, EXECUTION_TYPE = "ms-jointtarget", "rap-data", "rap-execution"
ROBOT_AXES = tuple(f"rax_{i}" for i in range(1, 7))
EXTERNAL_AXES = tuple(f"eax_{c}" for c in "abcdef")
AXES = (*ROBOT_AXES, *EXTERNAL_AXES)
"""The fields of ``ms-jointtarget``, degrees (mm for a linear axis)."""
XHTML_V1 = "application/xhtml+xml"
JSON_V1 = "application/json"
XHTML_V2 = "application/xhtml+xml;v=2.0"
HAL_V2 = "application/hal+json;v=2.0"
FORM_V1 = "application/x-www-form-urlencoded"
FORM_V2 = "application/x-www-form-urlencoded;v=2.0"
XHTML_NS = "http://www.w3.org/1999/xhtml"
DIGEST_REALM = "validusers@robapi.abb"
"""The realm an IRC5 names in its digest challenge."""
SESSION_COOKIES = ("-http-session-", "ABBCX")
"""The cookies that carry a logged-in session (RWS keeps at most 70 sessions: reuse one)."""


class PayloadError(TwinError):
    """A controller answer that is not the documented payload."""


def jointtarget_path(unit: str = MECHUNIT) -> str:
    """The jointtarget resource of a mechanical unit (both versions)."""
    return f"/rw/motionsystem/mechunits/{unit}/jointtarget"


def symbol_path(version: int, task: str, module: str, symbol: str) -> str:
    """A RAPID symbol's data resource."""
    if version == 1:
        return f"/rw/rapid/symbol/data/RAPID/{task}/{module}/{symbol}"
    return f"/rw/rapid/symbol/RAPID/{task}/{module}/{symbol}/data"


def set_symbol_query(version: int) -> dict[str, str]:
    """The URL parameters of setting a symbol: RWS 1.0 names the action; RWS 2.0 takes the
    RAPID mastership for the one request."""
    return {"action": "set"} if version == 1 else {"mastership": "implicit"}


EXECUTION_PATH = "/rw/rapid/execution"
LOGOUT_PATH = "/logout"


def position_path(version: int, unit: str = MECHUNIT) -> tuple[str, dict[str, str]]:
    """Where a virtual controller's unit is set to joint values, and the URL parameters."""
    if version == 1:
        return f"/rw/motionsystem/mechunits/{unit}", {"action": "mechunit-position"}
    return f"/rw/motionsystem/mechunits/{unit}/position", {}


def form_type(version: int) -> str:
    """The content type of a request body."""
    return FORM_V1 if version == 1 else FORM_V2


def accept_type(version: int, payload: str) -> str | None:
    """The ``Accept`` header a request sends (RWS 1.0 asks for JSON with ``json=1``)."""
    if version == 1:
        return None
    return HAL_V2 if payload == "json" else XHTML_V2


class State(NamedTuple):
    """One state item of an answer."""

    type: str
    """Its ``_type`` (JSON) or ``class`` (XHTML)."""
    title: str
    """Its ``_title`` or ``title``."""
    fields: dict[str, str]
    """Its values, as text."""


def _json_states(document: object) -> list[dict[str, object]]:
    if not isinstance(document, dict):
        return []
    embedded = document.get("_embedded")
    states = embedded.get("_state") if isinstance(embedded, dict) else document.get("state")
    return [item for item in states if isinstance(item, dict)] if isinstance(states, list) \
        else []


def _xhtml_items(body: bytes) -> ElementTree.Element:
    try:
        return ElementTree.fromstring(body)
    except ElementTree.ParseError as exc:
        raise PayloadError(f"an answer that is not XHTML ({exc})") from None


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def parse_states(body: bytes, content_type: str) -> list[State]:
    """Every state item of an RWS answer, JSON (1.0 or 2.0) or XHTML.

    Raises:
        PayloadError: if the body is neither.
    """
    if "json" in content_type:
        try:
            document = json.loads(body)
        except ValueError:
            raise PayloadError(f"an answer of type {content_type} that is not JSON") from None
        return [State(str(item.get("_type", "")), str(item.get("_title", "")),
                      {k: str(v) for k, v in item.items() if not k.startswith("_")})
                for item in _json_states(document)]
    root = _xhtml_items(body)
    states = []
    for element in root.iter():
        if _local(element.tag) != "li":
            continue
        fields = {span.get("class", ""): (span.text or "").strip()
                  for span in element if _local(span.tag) == "span"}
        states.append(State(element.get("class", ""), element.get("title", ""), fields))
    return states


def find_state(body: bytes, content_type: str, state_type: str) -> State:
    """The state item of a type.

    Raises:
        PayloadError: if the answer has none.
    """
    for state in parse_states(body, content_type):
        if state.type == state_type:
            return state
    raise PayloadError(f"an answer without a {state_type!r} item")


def parse_status(body: bytes, content_type: str) -> str:
    """The controller's error message (``code: msg``) of an error answer, or ""."""
    try:
        if "json" in content_type:
            document = json.loads(body)
            if isinstance(document, dict) and isinstance(document.get("_embedded"), dict):
                document = document["_embedded"]
            status = document.get("status", {}) if isinstance(document, dict) else {}
            return ": ".join(str(status[k]) for k in ("code", "msg") if k in status)
        root = _xhtml_items(body)
    except (ValueError, PayloadError):
        return ""
    for element in root.iter():
        if _local(element.tag) == "div" and element.get("class") == "status":
            parts = {span.get("class"): (span.text or "").strip() for span in element}
            return ": ".join(parts[k] for k in ("code", "msg") if parts.get(k))
    return ""


def _attribute(value: str) -> str:
    """``value`` as a quoted XML attribute value. (xml.sax.saxutils.quoteattr would do, but its
    module imports urllib.request and with it ssl: 48 ms of every twin command's start, which
    imports this module for the names of its environment variables.)"""
    return f'"{html.escape(value, quote=True)}"'


def render_state(version: int, payload: str, base: str, state: State) -> tuple[bytes, str]:
    """An answer holding one state item, as a controller writes it: ``(body, content type)``."""
    if payload == "json":
        item = {"_type": state.type, "_title": state.title, **state.fields}
        links = {"base": {"href": base}, "self": {"href": ""}}
        document: dict[str, object] = {"_links": links, "_embedded": {"_state": [item]}} \
            if version == 1 else {"_links": links, "status": {"code": 294912}, "state": [item]}
        return json.dumps(document).encode(), JSON_V1 if version == 1 else HAL_V2
    spans = "".join(f'<span class={_attribute(k)}>{html.escape(v, quote=False)}</span>'
                    for k, v in state.fields.items())
    body = (f'<?xml version="1.0" encoding="UTF-8"?><html xmlns="{XHTML_NS}"><head>'
            f'<title>rws</title><base href={_attribute(base)}/></head><body>'
            f'<div class="state"><ul><li class={_attribute(state.type)} '
            f'title={_attribute(state.title)}>{spans}</li></ul></div></body></html>')
    return body.encode(), XHTML_V1 if version == 1 else XHTML_V2


def render_status(version: int, payload: str, code: int, message: str) -> tuple[bytes, str]:
    """An error answer with the controller's status code and message."""
    if payload == "json":
        status = {"code": code, "msg": message}
        document = {"_embedded": {"status": status}} if version == 1 else {"status": status}
        return json.dumps(document).encode(), JSON_V1 if version == 1 else HAL_V2
    body = (f'<?xml version="1.0" encoding="UTF-8"?><html xmlns="{XHTML_NS}"><body>'
            f'<div class="status"><span class="code">{code}</span>'
            f'<span class="msg">{html.escape(message, quote=False)}</span></div></body></html>')
    return body.encode(), XHTML_V1 if version == 1 else XHTML_V2


def rapid_list(values: list[float]) -> str:
    """A RAPID array literal of numbers to 1e-6, ``[1.000000,2.500000]``."""
    return "[" + ",".join(f"{v:.6f}" for v in values) + "]"
