"""Encoder settings from a serial URL or a device TOML file.

A URL names the port and overrides any default in its query::

    serial:///dev/ttyUSB0?baud=115200&protocol=ascii
    serial:///dev/ttyUSB0?protocol=modbus&slave=3&register=100&word_order=little

A device TOML file holds the same keys, with ``port`` for the path::

    port = "/dev/ttyUSB0"
    protocol = "ascii"
    baud = 9600
    query = "MEAS?\\r\\n"

Defaults: 9600 baud, 8 data bits, no parity, 1 stop bit (8N1), ASCII protocol. Every key is
listed in :data:`KEYS`; an unknown key or a bad value is an :class:`~twin.errors.InputError`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any
from urllib.parse import parse_qsl, quote, urlsplit

from twin.errors import InputError, UnknownChoiceError
from twin.hardware.encoders import ENCODERS
from twin.io.paths import read_toml
from twin.io.table import Table
from twin.units import LENGTH_FACTORS

if TYPE_CHECKING:
    pass

PARITIES = ("N", "E", "O", "M", "S")
WORD_ORDERS = ("big", "little")
"""Modbus 32-bit word order: ``big`` high word first (ABCD), ``little`` low word first (CDAB)."""
VALUE_TYPES = ("int32", "int16", "float32")
MAX_TIMEOUT_S = 3600.0
"""Longest wait for one answer, s."""
FUNCTIONS = (3, 4)
"""Modbus read functions: 3 = holding registers, 4 = input registers."""


@dataclass(frozen=True)
class EncoderConfig:
    """How to talk to one drawstring encoder.

    Attributes:
        port: Serial device path, e.g. ``/dev/ttyUSB0``.
        protocol: ``ascii`` (query/answer lines) or ``modbus`` (Modbus RTU registers).
        baud: Baud rate.
        bytesize: Data bits (5–8).
        parity: ``N``, ``E``, ``O``, ``M`` or ``S``.
        stopbits: Stop bits (1, 1.5 or 2).
        timeout: Time to wait for a whole answer, s.
        query: ASCII: bytes sent to ask for one reading.
        pattern: ASCII: regular expression the stripped answer line must match in full; its
            first group (or the whole match) is the number.
        slave: Modbus: slave id (1–247).
        register: Modbus: address of the first register of the value.
        function: Modbus: 3 (holding) or 4 (input registers).
        word_order: Modbus: ``big`` (high word first) or ``little`` for 32-bit values.
        type: Modbus: ``int32``, ``int16`` or ``float32``.
        scale: Device value times ``scale`` is the length in ``unit``.
        unit: ``mm`` or ``m``.
        min: Smallest plausible length, in ``unit``; a reading below it is a fault.
        max: Largest plausible length (the encoder's range), in ``unit``.
    """

    port: str
    protocol: str = "ascii"
    baud: int = 9600
    bytesize: int = 8
    parity: str = "N"
    stopbits: float = 1
    timeout: float = 1.0
    query: str = "MEAS?\r\n"
    pattern: str = r"([+-]?\d+(?:\.\d*)?)"
    slave: int = 1
    register: int = 0
    function: int = 3
    word_order: str = "big"
    type: str = "int32"
    scale: float = 1.0
    unit: str = "mm"
    min: float = 0.0
    max: float = 10000.0

    def __post_init__(self) -> None:
        checks: list[tuple[str, bool, str]] = [
            ("port", bool(self.port), "a device path"),
            ("baud", self.baud > 0, "a positive baud rate"),
            ("bytesize", self.bytesize in (5, 6, 7, 8), "5, 6, 7 or 8"),
            ("stopbits", self.stopbits in (1, 1.5, 2), "1, 1.5 or 2"),
            ("timeout", 0 < self.timeout <= MAX_TIMEOUT_S, f"a time in (0, {MAX_TIMEOUT_S:g}] s"),
            ("query", bool(self.query), "a non-empty query"),
            ("slave", 1 <= self.slave <= 247, "a slave id in 1..247"),
            ("register", 0 <= self.register <= 65535, "a register address in 0..65535"),
            ("scale", math.isfinite(self.scale) and self.scale != 0, "a finite non-zero scale"),
            ("max", math.isfinite(self.min) and math.isfinite(self.max) and self.min < self.max,
             "finite min < max"),
        ]
        for key, ok, expected in checks:
            if not ok:
                raise InputError(f"{getattr(self, key)!r}", expected, where=key)
        for key, choices in (("protocol", tuple(ENCODERS)), ("parity", PARITIES),
                             ("function", FUNCTIONS), ("word_order", WORD_ORDERS),
                             ("type", VALUE_TYPES), ("unit", tuple(LENGTH_FACTORS))):
            if getattr(self, key) not in choices:
                raise UnknownChoiceError(key, str(getattr(self, key)), map(str, choices))
        try:
            re.compile(self.pattern)
        except re.error as exc:
            raise InputError(f"{self.pattern!r} ({exc})", "a regular expression",
                             where="pattern") from None

    @property
    def m_per_count(self) -> float:
        """Metres per device count: ``scale`` in ``unit`` converted to m."""
        return self.scale * LENGTH_FACTORS[self.unit]

    @property
    def range_m(self) -> tuple[float, float]:
        """Plausible lengths ``(min, max)``, m."""
        factor = LENGTH_FACTORS[self.unit]
        return self.min * factor, self.max * factor

    def to_url(self) -> str:
        """The URL that gives back this configuration (only keys that differ from defaults)."""
        defaults = EncoderConfig(port=self.port)
        items = [
            f"{f.name}={quote(str(getattr(self, f.name)), safe='')}"
            for f in fields(self)
            if f.name == "protocol"
            or (f.name != "port" and getattr(self, f.name) != getattr(defaults, f.name))
        ]
        return f"serial://{quote(self.port)}?" + "&".join(items)


KEYS = tuple(f.name for f in fields(EncoderConfig))
TEXT_KEYS: dict[str, Callable[[str], str]] = {
    "port": str, "protocol": str.lower, "parity": str.upper, "query": str, "pattern": str,
    "word_order": str.lower, "type": str.lower, "unit": str.lower}
"""The keys whose value is text, each with the case it is read in."""
INTEGER_KEYS = ("baud", "bytesize", "slave", "register", "function")
NUMBER_KEYS = {"stopbits": "1, 1.5 or 2", "timeout": f"a time in (0, {MAX_TIMEOUT_S:g}] s",
               "scale": "a finite non-zero scale", "min": "a finite number",
               "max": "a finite number"}
"""The keys whose value is a number, each with what a non-number is told to be."""


def config_from_mapping(values: dict[str, Any], source: str) -> EncoderConfig:
    """Build a config from ``{key: value}`` as given in a URL query or a TOML file (numbers may
    be written as text in either)."""
    table = Table(values, source, allowed=KEYS, numbers_as_text=True)
    table.required("port", "the serial device path")
    typed: dict[str, Any] = {}
    for key in table.values:
        if key in TEXT_KEYS:
            typed[key] = TEXT_KEYS[key](table.text(key))
        elif key in INTEGER_KEYS:
            typed[key] = table.integer(key)
        else:
            typed[key] = table.number(key, expected=NUMBER_KEYS[key])
    try:
        return EncoderConfig(**typed)
    except InputError as exc:
        raise InputError(exc.found, exc.expected, source=source, where=exc.where) from None


def parse_url(url: str) -> EncoderConfig:
    """Parse ``serial:///dev/ttyUSB0?baud=115200&protocol=ascii``.

    Raises:
        InputError: naming the URL and the key that is wrong.
    """
    parts = urlsplit(url)
    if parts.scheme != "serial" or not parts.path or parts.netloc:
        raise InputError(f"{url!r}", "serial:///path/to/device?key=value&… or a device TOML file",
                         source="--encoder")
    values: dict[str, Any] = {"port": parts.path}
    for key, value in parse_qsl(parts.query, keep_blank_values=True, strict_parsing=False):
        if key in values:
            raise InputError(f"{key!r} twice", "each key once", source=url)
        values[key] = value
    return config_from_mapping(values, url)


def load_device(path: str | Path) -> EncoderConfig:
    """Read a device TOML file (the URL keys, with ``port``)."""
    document = read_toml(path, "a device TOML file")
    return config_from_mapping(document, str(path))


def resolve(spec: str) -> EncoderConfig:
    """``--encoder`` value: a ``serial://`` URL or the path of a device TOML file."""
    return parse_url(spec) if spec.startswith("serial:") else load_device(spec)
