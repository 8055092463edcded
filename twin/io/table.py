"""The one validator of config tables: scenario, robot, capture, study, expectations, encoder.

Every loader reads its file with :func:`twin.io.paths.read_toml` (or a URL's query) and its
values through a :class:`Table`: typed getters that check type, finiteness and range, and turn
every mistake into one :class:`~twin.errors.InputError` naming the file, the key, what was found
and what was expected::

    robot.toml: joint 1 d: found 1e+300, expected a number within ±1e+06 mm
    scenario.toml: [poses] count: found 1000000000, expected an integer in 1..100000

A TOML boolean is never a number here (Python's ``True`` is an ``int``): the check is made once,
in this module, for every loader.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from twin.arrays import Array
from twin.errors import InputError


def _is_number(value: object) -> bool:
    """A finite int or float, not a boolean."""
    return isinstance(value, int | float) and not isinstance(value, bool) \
        and math.isfinite(value)


def _bounds(minimum: float | None, maximum: float | None, strict_minimum: bool,
            strict_maximum: bool) -> str:
    """`` > 0 <= 1`` and the like: the bounds a number must keep, for a message."""
    low = "" if minimum is None else f" {'>' if strict_minimum else '>='} {minimum:g}"
    high = "" if maximum is None else f" {'<' if strict_maximum else '<='} {maximum:g}"
    return low + high



SHOWN_CHARS = 60
"""Longest value an error quotes from a file (a list of a million numbers is not echoed)."""


def shown(value: object) -> str:
    """A value as an error quotes it: its repr, cut short."""
    text = repr(value)
    return text if len(text) <= SHOWN_CHARS else text[:SHOWN_CHARS] + "…"

class Table:
    """Typed access to one table of a config file.

    Args:
        values: The table as parsed (a mapping of key to value).
        source: The file (or URL) it comes from, named by every error.
        where: Where the table is in the file, as messages show it: ``""`` for the top level,
            ``"[calibration]"`` for a TOML table, ``"joint 1"`` for an item of a list.
        allowed: The keys the table may hold (None: any); another key is an error.
        kind: What the table is, said beside the allowed keys (``"a hayati joint"``).
        numbers_as_text: Whether numbers may be written as text (a URL's query): ``"9600"``
            is read as 9600, ``"0x10"`` as 16.

    Raises:
        InputError: if ``values`` is not a table, or holds a key not in ``allowed``.
    """

    def __init__(self, values: object, source: str | Path | None, where: str = "", *,
                 allowed: Iterable[str] | None = None, kind: str = "",
                 numbers_as_text: bool = False) -> None:
        self.source, self.name, self.numbers_as_text = source, where, numbers_as_text
        if not isinstance(values, Mapping):
            raise InputError(shown(values), "a table", source=source, where=where or None)
        self.values: Mapping[str, Any] = values
        if allowed is not None:
            allowed = tuple(allowed)
            unknown = sorted(set(values) - set(allowed))
            if unknown:
                raise InputError(f"unknown key {shown(unknown[0])}",
                                 "only " + ", ".join(allowed) + (f" ({kind})" if kind else ""),
                                 source=source, where=where or None)

    def where(self, key: str) -> str:
        """Where ``key`` is, as messages show it."""
        return f"{self.name} {key}" if self.name else key

    def error(self, key: str | None, found: str, expected: str) -> InputError:
        """The error of ``key`` (or of the whole table, for None)."""
        return InputError(found, expected, source=self.source,
                          where=self.name or None if key is None else self.where(key))

    def has(self, key: str) -> bool:
        """Whether the table holds ``key``."""
        return key in self.values

    def required(self, key: str, expected: str) -> Any:
        """The value of ``key`` as written; an error naming ``expected`` when it is absent."""
        if key not in self.values:
            raise self.error(key, "nothing", expected)
        return self.values[key]

    def table(self, key: str, *, allowed: Iterable[str] | None = None, kind: str = "",
              expected: str = "a table") -> Table:
        """The table under ``key`` (an empty one when absent): ``[key]`` under the top level,
        ``[this.key]`` under a TOML table."""
        nested = not self.name or self.name.startswith("[")
        where = f"[{self.name[1:-1]}.{key}]" if self.name.startswith("[") \
            else f"[{key}]" if nested else self.where(key)
        value = self.values.get(key, {})
        if not isinstance(value, Mapping):
            raise InputError(shown(value), expected, source=self.source, where=where)
        return Table(value, self.source, where, allowed=allowed, kind=kind,
                     numbers_as_text=self.numbers_as_text)

    def _number(self, value: object) -> float | None:
        """``value`` as a finite number, or None."""
        if self.numbers_as_text and isinstance(value, str):
            try:
                value = float(value)
            except ValueError:
                return None
        return float(value) if _is_number(value) else None  # type: ignore[arg-type]

    def number(self, key: str, default: float | None = None, *, minimum: float | None = None,
               maximum: float | None = None, strict_minimum: bool = False,
               strict_maximum: bool = False, expected: str | None = None) -> float:
        """A finite number within the bounds (``default`` when absent)."""
        value = self.values.get(key, default)
        expected = expected or "a number" + _bounds(minimum, maximum, strict_minimum,
                                                    strict_maximum)
        if value is None:
            raise self.error(key, "nothing", expected)
        number = self._number(value)
        if number is None \
                or (minimum is not None and (number <= minimum if strict_minimum
                                             else number < minimum)) \
                or (maximum is not None and (number >= maximum if strict_maximum
                                             else number > maximum)):
            raise self.error(key, shown(value), expected)
        return number

    def integer(self, key: str, default: int | None = None, *, minimum: int | None = None,
                maximum: int | None = None, expected: str | None = None) -> int:
        """A whole number within the bounds (``default`` when absent)."""
        value = self.values.get(key, default)
        if expected is None:
            expected = "an integer" + (f" in {minimum}..{maximum}" if minimum is not None
                                       and maximum is not None
                                       else _bounds(minimum, maximum, False, False))
        number: int | None = value if isinstance(value, int) \
            and not isinstance(value, bool) else None
        if self.numbers_as_text and isinstance(value, str):
            try:
                number = int(value, 0)
            except ValueError:
                number = None
        if number is None or (minimum is not None and number < minimum) \
                or (maximum is not None and number > maximum):
            raise self.error(key, "nothing" if value is None else shown(value), expected)
        return number

    def boolean(self, key: str, default: bool | None = None) -> bool:
        """``true`` or ``false`` (``default`` when absent)."""
        value = self.values.get(key, default)
        if not isinstance(value, bool):
            raise self.error(key, "nothing" if value is None else shown(value), "true or false")
        return value

    def text(self, key: str, default: str | None = None, *,
             choices: Sequence[str] | None = None, expected: str | None = None) -> str:
        """A string, one of ``choices`` when given (``default`` when absent)."""
        value = self.values.get(key, default)
        if not isinstance(value, str) or (choices is not None and value not in choices):
            raise self.error(key, "nothing" if value is None else shown(value), expected or (
                "a string" if choices is None else "one of " + ", ".join(choices)))
        return value

    def strings(self, key: str, default: list[str] | None = None, *,
                choices: Sequence[str] | None = None, distinct: bool = False,
                expected: str) -> list[str]:
        """A non-empty list of strings (among ``choices``, each once if ``distinct``)."""
        value = self.values.get(key, default)
        if not isinstance(value, list) or not value \
                or not all(isinstance(item, str) for item in value) \
                or (choices is not None and not set(value) <= set(choices)) \
                or (distinct and len(set(value)) != len(value)):
            raise self.error(key, "nothing" if value is None else shown(value), expected)
        return list(value)

    def vector(self, key: str, length: int, *, per_joint: bool = False,
               minimum: float | None = None, within: float | None = None,
               default: float | list[float] | None = None,
               expected: str | None = None) -> Array:
        """A list of ``length`` finite numbers (or one number for all, when ``per_joint``), each
        at least ``minimum`` and within ±``within`` when given, shape (length,)."""
        value = self.values.get(key, default)
        expected = expected or (f"{length} numbers"
                                + (" (or one for all joints)" if per_joint else "")
                                + _bounds(minimum, None, False, False)
                                + (f" within ±{within:g}" if within is not None else ""))
        items = [value] * length if per_joint and _is_number(value) else value
        if not isinstance(items, list) or len(items) != length or any(
                not _is_number(v) or (minimum is not None and v < minimum)
                or (within is not None and abs(v) > within) for v in items):
            raise self.error(key, "nothing" if value is None else shown(value), expected)
        return np.array(items, dtype=np.float64)

    def rows(self, key: str, width: int, *, expected: str) -> Array:
        """A non-empty list of lists of ``width`` finite numbers, shape (k, width)."""
        value = self.values.get(key)
        if not isinstance(value, list) or not value or any(
                not isinstance(row, list) or len(row) != width
                or not all(_is_number(v) for v in row) for row in value):
            raise self.error(key, "nothing" if value is None else shown(value), expected)
        return np.array(value, dtype=np.float64)
