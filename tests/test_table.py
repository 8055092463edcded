"""The one config validator: each mistake one line naming the file, the key, what was found and
what was expected."""

from __future__ import annotations

import numpy as np
import pytest

from twin.errors import InputError
from twin.io.table import Table


def _message(call: object) -> str:
    with pytest.raises(InputError) as caught:
        call()  # type: ignore[operator]
    return str(caught.value)


def test_a_boolean_is_not_a_number() -> None:
    """TOML's true is Python's int 1: every numeric getter refuses it."""
    table = Table({"count": True, "scale": False, "xyz": [1.0, True, 3.0]}, "f.toml", "[poses]")
    assert _message(lambda: table.integer("count", minimum=1)) == \
        "f.toml: [poses] count: found True, expected an integer >= 1"
    assert "[poses] scale: found False, expected a number" in _message(
        lambda: table.number("scale"))
    assert "[poses] xyz: found [1.0, True, 3.0], expected 3 numbers" in _message(
        lambda: table.vector("xyz", 3))


def test_unknown_keys_and_nested_tables_are_named() -> None:
    """An unknown key lists the allowed ones; a table inside a table is [outer.inner]."""
    assert _message(lambda: Table({"colour": 1}, "s.toml", allowed=("name", "seed"))) == \
        "s.toml: found unknown key 'colour', expected only name, seed"
    top = Table({"port": {"stations_mm": {"a": [1.0, 2.0]}}}, "s.toml")
    stations = top.table("port").table("stations_mm")
    assert _message(lambda: stations.vector("a", 3)) == \
        "s.toml: [port.stations_mm] a: found [1.0, 2.0], expected 3 numbers"
    assert _message(lambda: Table({"study": 3}, "s.toml").table("study")) == \
        "s.toml: [study]: found 3, expected a table"


def test_bounds_missing_values_and_choices() -> None:
    """Bounds are stated as they are checked; a missing required value is 'nothing'."""
    table = Table({"share": 1.0, "stop": "fast", "errors": ["dh", "dh"]}, "c.toml",
                  "[calibration]")
    assert "found 1.0, expected a number > 0 < 1" in _message(lambda: table.number(
        "share", minimum=0.0, maximum=1.0, strict_minimum=True, strict_maximum=True))
    assert "[calibration] seed: found nothing, expected an integer" in _message(
        lambda: table.integer("seed"))
    assert "stop: found 'fast', expected one of converge, paper" in _message(
        lambda: table.text("stop", choices=("converge", "paper")))
    assert "errors: found ['dh', 'dh'], expected distinct" in _message(
        lambda: table.strings("errors", distinct=True, expected="distinct groups"))
    assert table.number("missing", 0.5) == 0.5


def test_numbers_written_as_text() -> None:
    """A URL's query holds text: with numbers_as_text, "9600" and "0x10" are numbers; words
    are still refused."""
    table = Table({"baud": "9600", "register": "0x10", "timeout": "0.5", "parity": "x"},
                  "serial:///dev/ttyS0", numbers_as_text=True)
    assert table.integer("baud") == 9600 and table.integer("register") == 16
    assert table.number("timeout") == 0.5
    assert _message(lambda: table.integer("parity")) == \
        "serial:///dev/ttyS0: parity: found 'x', expected an integer"
    assert _message(lambda: Table({"baud": "9600"}, "d.toml").integer("baud")) == \
        "d.toml: baud: found '9600', expected an integer"


def test_vectors_one_for_all_and_rows() -> None:
    """per_joint takes one number for all joints; rows are lists of equal width."""
    table = Table({"a_mm": 1.0, "sockets": [[0, 0, 0], [50, 0, 0]]}, "s.toml", "[x]")
    np.testing.assert_array_equal(table.vector("a_mm", 3, per_joint=True), [1.0, 1.0, 1.0])
    assert table.rows("sockets", 3, expected="points").shape == (2, 3)
    assert "found [[0, 0, 0], [50, 0, 0]], expected points" in _message(
        lambda: table.rows("sockets", 2, expected="points"))
