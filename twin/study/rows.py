"""The rows of a study's `results.csv`: one :class:`TrialRow` per trial × method.

The file's columns are the fields of :class:`TrialRow`, in their order, and their types say
how each is written and read back. Adding a column is one field here (and its value where rows
are made, :func:`twin.study.trial.run_trial`): the header, the writer, the reader and the
columns an expectation may name (:mod:`twin.study.expect`) follow from it.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable, Sequence
from typing import NamedTuple, get_type_hints


class TrialRow(NamedTuple):
    """One method's result on one trial of a study. Lengths in mm, times in s."""

    trial: int
    """Trial index within the case, 0-based."""
    case: str
    """Label of the sweep point ("" without a sweep)."""
    seed: int
    """Seed of the trial's draws (perturbation, poses, noise, split, methods)."""
    method: str
    """The method's name."""
    before_rmse_mm: float
    """Validation residuals of the nominal model: RMSE."""
    before_mae_mm: float
    """… mean absolute error (the paper's "STD")."""
    before_std_mm: float
    """… standard deviation."""
    before_max_mm: float
    """… largest absolute residual."""
    train_rmse_mm: float
    """Training residuals after calibration: RMSE."""
    train_mae_mm: float
    train_std_mm: float
    train_max_mm: float
    validation_rmse_mm: float
    """Validation residuals after calibration: RMSE."""
    validation_mae_mm: float
    validation_std_mm: float
    validation_max_mm: float
    flange_error_mm: float
    """RMS flange-position error over the workspace against the true geometry."""
    crlb_mm: float
    """Its Cramér–Rao bound."""
    crlb_ratio: float
    """``flange_error_mm / crlb_mm`` (NaN where the bound is zero: no noise)."""
    iterations: int
    evaluations: int
    seconds: float
    """Wall time of the method."""
    converged: bool
    """A convergence test (ftol, xtol, gtol) fired at the point returned."""
    stop_reason: str
    """The test that stopped each stage, joined by ``+`` for cascades (``gtol+stalled``)."""
    flange_error_gauge_free_mm: float
    """The flange error modulo the motions the data cannot see (:mod:`twin.analysis.gauge`: a turn
    about joint 1's axis with an estimated port…)."""
    crlb_ratio_gauge_free: float
    """Its ratio to the bound."""
    point_error_mm: float
    """The same for the measured point (eyelet, tracker target, ball: what an estimated
    attachment identifies)."""
    point_crlb_ratio: float
    """Its ratio to that point's Cramér–Rao bound."""

    def number(self, column: str) -> float:
        """A numeric or boolean column (:data:`NUMERIC_COLUMNS`, :data:`BOOLEAN_COLUMNS`) as a
        float, booleans as 0 or 1: what statistics over trials take."""
        if column not in NUMERIC_COLUMNS + BOOLEAN_COLUMNS:
            raise KeyError(f"{column!r}: expected one of "
                           + ", ".join(NUMERIC_COLUMNS + BOOLEAN_COLUMNS))
        return float(getattr(self, column))


COLUMNS: tuple[str, ...] = TrialRow._fields
"""Columns of `results.csv`, in order."""
IDENTITY_COLUMNS = ("trial", "case", "seed", "method")
"""Which trial and method a row is; not results."""
_TYPES: dict[str, type] = get_type_hints(TrialRow)
BOOLEAN_COLUMNS = tuple(c for c in COLUMNS if _TYPES[c] is bool)
NUMERIC_COLUMNS = tuple(c for c in COLUMNS if _TYPES[c] in (int, float)
                        and c not in IDENTITY_COLUMNS)
"""Result columns with a number: what statistics and expectations may name."""
HEADER = ",".join(COLUMNS) + "\n"
"""The first line of `results.csv`."""


def _format(value: bool | int | float | str) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        # repr: the shortest text that reads back to the same float.
        return repr(value)
    return str(value)


def format_rows(rows: Iterable[TrialRow]) -> str:
    """Rows as lines of `results.csv` (no header), each ending with LF."""
    text = io.StringIO()
    csv.writer(text, lineterminator="\n").writerows([_format(v) for v in row] for row in rows)
    return text.getvalue()


def _parse(kind: type, text: str) -> bool | int | float | str:
    if kind is bool:
        return text == "true"
    return kind(text)


def parse_row(values: Sequence[str]) -> TrialRow:
    """A row from the fields of one line of `results.csv`.

    Raises:
        ValueError: if a number does not read, or the fields are not as many as the columns.
    """
    return TrialRow._make(_parse(_TYPES[c], v) for c, v in zip(COLUMNS, values, strict=True))
