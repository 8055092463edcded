"""Expectations: what a study's results must show against the truth, checked by `twin check`.

A scenario's ``[expect]`` table (or the same table in a file given with ``--expect``) maps a
method name or alias (or several, comma-separated), or ``"*"`` for every method of the study, to
a list of strings ``"COLUMN STAT OP VALUE"``::

    [expect]
    lm  = ["flange_error_mm p95 <= 0.03", "crlb_ratio median <= 1.5"]
    "ekf,ukf-vslm" = ["crlb_ratio median <= 1.2"]
    "*" = ["validation_rmse_mm mean <= 0.02", "converged share >= 0.9"]

- ``COLUMN``: a numeric column of `results.csv` (:data:`NUMERIC_COLUMNS`, in its unit: mm, s,
  a count, or the bound ratio), or the boolean ``converged`` with STAT ``share``.
- ``STAT`` over the method's trials (of one sweep point): ``mean``, ``median``, ``rms`` (root mean
square over the trials), ``min``,
  ``max``, ``std`` (sample, ddof = 1: two trials at least), ``p5`` … ``p99`` (percentiles,
  linear interpolation between order statistics, numpy's default), ``share`` (of true).
- ``OP``: ``<=``, ``<``, ``>=``, ``>``; it also says which way is better when a study is compared
  with a baseline (``<=``/``<``: lower is better).
- ``VALUE``: a finite number; a share is in [0, 1].

A column with a non-finite value (``crlb_ratio`` is NaN where the bound is zero, i.e. without
noise) fails every expectation on it, and the report says how many trials were non-finite: an
expectation nobody can measure must not pass.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from twin.errors import InputError, UnknownChoiceError
from twin.io.paths import read_toml
from twin.io.table import Table
from twin.solvers import get_solver
from twin.study.rows import BOOLEAN_COLUMNS, NUMERIC_COLUMNS

ALL_METHODS = "*"
"""The ``[expect]`` key whose expectations apply to every method of the study."""
PERCENTILES = {f"p{q}": q for q in (5, 10, 25, 75, 90, 95, 99)}
STATS = ("mean", "median", "rms", "min", "max", "std", *PERCENTILES, "share")
OPERATORS = ("<=", "<", ">=", ">")
GRAMMAR = '"COLUMN STAT OP VALUE", e.g. "flange_error_mm p95 <= 0.03"'


@dataclass(frozen=True)
class Expectation:
    """One ``"COLUMN STAT OP VALUE"`` string, parsed.

    Attributes:
        column: A column of `results.csv`.
        stat: One of :data:`STATS`.
        op: One of :data:`OPERATORS`.
        value: The threshold, in the column's unit (a share for ``share``).
        text: The string as written.
    """

    column: str
    stat: str
    op: str
    value: float
    text: str

    def __post_init__(self) -> None:
        if self.stat not in STATS:
            raise ValueError(f"stat: expected one of {', '.join(STATS)}")
        if self.op not in OPERATORS:
            raise ValueError(f"op: expected one of {', '.join(OPERATORS)}")
        if (self.stat == "share") != (self.column in BOOLEAN_COLUMNS):
            raise ValueError("share: expected for the boolean columns only, and only share")
        if not math.isfinite(self.value):
            raise ValueError("value: expected a finite number")

    @property
    def lower_is_better(self) -> bool:
        """Whether the operator bounds the column from above (``<=``, ``<``)."""
        return self.op in ("<=", "<")

    def holds(self, measured: float) -> bool:
        """Whether ``measured OP value``; False for a non-finite ``measured``."""
        if not math.isfinite(measured):
            return False
        return {"<=": measured <= self.value, "<": measured < self.value,
                ">=": measured >= self.value, ">": measured > self.value}[self.op]


class Measured(NamedTuple):
    """An expectation's statistic over a method's trials."""

    value: float
    """The statistic, in the column's unit; NaN when it cannot be measured."""
    trials: int
    """Trials it was taken over."""
    nonfinite: int
    """Trials whose value in the column is NaN or infinite."""
    note: str
    """Why ``value`` is NaN, or ""."""


def measure_expectation(expectation: Expectation, values: Sequence[float]) -> Measured:
    """The statistic of ``expectation`` over one method's values of its column.

    Args:
        expectation: What to measure.
        values: The column's values, one per trial (booleans as 0/1).
    """
    array = np.asarray(values, dtype=np.float64)
    nonfinite = int(np.count_nonzero(~np.isfinite(array)))
    if array.size == 0:
        return Measured(math.nan, 0, 0, "no trials")
    if nonfinite:
        return Measured(math.nan, int(array.size), nonfinite,
                        f"{nonfinite} of {array.size} trials non-finite")
    stat = expectation.stat
    if stat == "std" and array.size < 2:
        return Measured(math.nan, 1, 0, "std needs 2 trials at least")
    if stat in PERCENTILES:
        value = float(np.percentile(array, PERCENTILES[stat]))
    elif stat in ("mean", "share"):
        value = float(np.mean(array))
    elif stat == "std":
        value = float(np.std(array, ddof=1))
    elif stat == "median":
        value = float(np.median(array))
    elif stat == "rms":
        value = float(np.sqrt(np.mean(array**2)))
    else:
        value = float(np.min(array) if stat == "min" else np.max(array))
    return Measured(value, int(array.size), 0, "")


def parse_expectation(text: Any, source: str | Path, where: str) -> Expectation:
    """Parse one ``"COLUMN STAT OP VALUE"`` string.

    Raises:
        InputError: naming ``source``, ``where`` (the method) and the string.
    """
    def error(found: str, expected: str) -> InputError:
        return InputError(f"{text!r}: {found}", expected, source=source, where=where)

    if not isinstance(text, str):
        raise InputError(f"{text!r}", GRAMMAR, source=source, where=where)
    words = text.split()
    if len(words) != 4:
        raise error(f"{len(words)} words", GRAMMAR)
    column, stat, op, number = words
    if column not in NUMERIC_COLUMNS + BOOLEAN_COLUMNS:
        raise error(f"unknown column {column!r}", "a column of results.csv: "
                    + ", ".join(NUMERIC_COLUMNS + BOOLEAN_COLUMNS))
    if stat not in STATS:
        raise error(f"unknown statistic {stat!r}", "one of " + ", ".join(STATS))
    if column in BOOLEAN_COLUMNS and stat != "share":
        raise error(f"{stat} of the boolean column {column}", f"{column} share")
    if stat == "share" and column not in BOOLEAN_COLUMNS:
        raise error(f"share of the numeric column {column}",
                    "share of a boolean column: " + ", ".join(BOOLEAN_COLUMNS))
    if op not in OPERATORS:
        raise error(f"unknown operator {op!r}", "one of " + ", ".join(OPERATORS))
    try:
        value = float(number)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise error(f"the value {number!r}", "a finite number in the column's unit")
    if stat == "share" and not 0.0 <= value <= 1.0:
        raise error(f"the share {number}", "a share from 0 to 1")
    return Expectation(column, stat, op, value, text)


def _method_name(key: str, methods: Sequence[str], source: str | Path) -> str:
    where = f"[expect] {key}"
    listed = ", ".join(methods)
    try:
        name = get_solver(key).name
    except UnknownChoiceError:
        name = key
    if name not in methods:
        raise InputError(
            f"method {key!r}, which is not in this study",
            f"one of the study's methods ({listed}) or \"*\"; add it with --methods, or give "
            "--expect FILE", source=source, where=where)
    return name


def parse_expect_table(table: Any, methods: Sequence[str], source: str | Path
                       ) -> tuple[tuple[str, Expectation], ...]:
    """Every (method, expectation) of an ``[expect]`` table, ``"*"`` expanded over ``methods``,
    in the table's order.

    Args:
        table: The ``[expect]`` table as parsed from TOML.
        methods: The study's method names.
        source: The file the table is in (or the argument that gave it), for messages.

    Raises:
        InputError: naming the file, the method and the string that are wrong.
    """
    expected = ('a table of method names to lists of expectations, e.g. '
                'lm = ["flange_error_mm p95 <= 0.03"]')
    if not isinstance(table, Mapping) or not table:
        raise InputError(f"{table!r}", expected, source=source, where="[expect]")
    expect = Table(table, source, "[expect]")
    pairs: list[tuple[str, Expectation]] = []
    for key, texts in expect.values.items():
        if not isinstance(texts, list) or not texts:
            raise expect.error(key, f"{texts!r}", f"a non-empty list of {GRAMMAR}")
        parsed = [parse_expectation(text, source, expect.where(key)) for text in texts]
        names = methods if key.strip() == ALL_METHODS else tuple(dict.fromkeys(
            _method_name(name.strip(), methods, source) for name in key.split(",")))
        pairs += [(name, expectation) for name in names for expectation in parsed]
    return tuple(pairs)


def read_expect_file(path: str | Path) -> dict[str, Any]:
    """The ``[expect]`` table of an expectations file (a TOML file with that table only).

    Raises:
        InputError: naming the file, if it is missing, not TOML, or holds anything else.
    """
    path = Path(path)
    document = Table(read_toml(path, "a TOML file with an [expect] table"), path,
                     allowed=("expect",), kind="an [expect] table and nothing else")
    if not document.has("expect"):
        raise InputError("no [expect] table", "an [expect] table", source=path)
    table: dict[str, Any] = document.values["expect"]
    return table
