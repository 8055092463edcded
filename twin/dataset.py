"""Measurements: joint angles and what an instrument read at each pose.

One row per pose. What was read, and how it is read, belongs to the measurement kind
(:mod:`twin.kinds`, named by :attr:`Measurements.kind`): a kind keeps its readings as named
columns of :attr:`~Measurements.values` (numbers, SI) and :attr:`~Measurements.labels` (a name per
row out of a list) — a cable length ``length_m`` and the ``port`` it ran from, a tracker's
``position_m``, the ``point`` a ball was set into. The kind's module makes its measurements
(``twin.kinds.length.length_measurements`` …) and is the one place that reads those columns.

Any other per-row quantity lives beside the readings in the same two mappings, under its own
name, whatever the kind: a time ``t_s``, a temperature ``temperature_c`` (values), the
``session`` a row was captured in (labels). Subsets, file columns and the model carry them
along without knowing them.

Optionally, the direction each joint last moved in before the reading (``approach``, ±1), which
backlash depends on.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import Array, frozen_array

TIME = "t_s"
"""The per-row column of each reading's time since the capture started, s."""
TEMPERATURE = "temperature_c"
"""The per-row column of the temperature at each reading (the arm's, or the cell's), °C."""
TEMPERATURE_RANGE_C = (-50.0, 150.0)
"""Temperatures a file may give, °C: beyond them an arm does not run (and 293 is a temperature
in kelvin)."""
REFERENCE = "reference"
"""The per-row column that flags a reference pose revisited during the capture (1, else 0):
what the drift test (:mod:`twin.analysis.drift`) reads."""
ROW_COLUMNS = (TIME, TEMPERATURE, REFERENCE)
"""The per-row columns any kind's measurements may carry beside their readings, in file
order."""


def reference_visits(count: int, every: int) -> NDArray[np.intp]:
    """The order a capture of ``count`` poses visits them in when it revisits the first pose
    (the reference) after every ``every`` of the others and at the end (``every`` 0: never):
    indices into the poses, shape (≥ count,); the reference rows are those equal to 0."""
    if every < 0:
        raise ValueError(f"every: {every}, expected >= 0")
    if not every or count < 2:
        return np.arange(count, dtype=np.intp)
    visits = [0]
    for start in range(1, count, every):
        visits += [*range(start, min(start + every, count)), 0]
    return np.array(visits, dtype=np.intp)


class Labels(NamedTuple):
    """A name per row out of a list: the port each cable ran from, the fixed point a ball sat
    in, the session a row was captured in."""

    names: tuple[str, ...]
    """The distinct names, in their order of first use (empty: unnamed, indices only)."""
    indices: NDArray[np.intp]
    """Each row's index into :attr:`names`, shape (m,)."""

    @classmethod
    def of(cls, labels: list[str] | tuple[str, ...]) -> Labels:
        """Labels from one name per row: distinct names in order of first appearance."""
        names = tuple(dict.fromkeys(labels))
        return cls(names, np.array([names.index(label) for label in labels], dtype=np.intp))

    def per_row(self, prefix: str = "") -> list[str]:
        """Each row's name (unnamed indices as ``prefix`` and the 1-based index)."""
        names = self.names or tuple(f"{prefix}{j + 1}"
                                    for j in range(int(self.indices.max(initial=-1)) + 1))
        return [names[j] for j in self.indices]


def _labels(labels: Labels, m: int, what: str) -> Labels:
    index = np.asarray(labels.indices)
    if index.shape != (m,) or (index.size and (not np.issubdtype(index.dtype, np.integer)
                                               or index.min() < 0)):
        raise ValueError(f"{what}: expected {m} non-negative integers, got {index.shape}")
    names = tuple(str(name) for name in labels.names)
    if names and index.size and index.max() >= len(names):
        raise ValueError(f"{what}: {len(names)} names for the {what} indices")
    frozen = np.array(index, dtype=np.intp)
    frozen.setflags(write=False)
    return Labels(names, frozen)


@dataclass(frozen=True)
class Measurements:
    """Joint angles and readings, one row per pose (module docstring).

    Attributes:
        q_rad: Recorded joint angles, shape (m, n), rad.
        kind: The measurement kind's name (:data:`twin.kinds.KINDS`); the kind's module makes
            and reads its columns.
        values: Numeric columns by name, each shape (m, ...), SI (the kind's readings, and any
            other per-row quantity).
        labels: Named columns by name (the kind's, and any other).
        approach: Direction each joint last moved in before the reading, shape (m, n), +1 or
            −1 (int8 labels); None when not recorded.
    """

    q_rad: Array
    kind: str
    values: Mapping[str, Array] = field(default_factory=dict)
    labels: Mapping[str, Labels] = field(default_factory=dict)
    approach: NDArray[np.int8] | None = None

    def __post_init__(self) -> None:
        q = np.asarray(self.q_rad, dtype=np.float64)
        if q.ndim != 2:
            raise ValueError(f"q_rad: shape {q.shape}, expected (m, n)")
        m, n = q.shape
        object.__setattr__(self, "q_rad", frozen_array(q, (m, n), "q_rad"))
        if not self.kind:
            raise ValueError("kind: expected the name of a measurement kind")
        values = {}
        for name, column in self.values.items():
            array = np.asarray(column, dtype=np.float64)
            values[name] = frozen_array(array, (m, *array.shape[1:]), name)
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "labels", {name: _labels(Labels(*labels), m, name)
                                            for name, labels in self.labels.items()})
        if self.approach is not None:
            labels = np.asarray(self.approach)
            # Labels, not measured values: each must be one of the two directions exactly.
            if labels.shape != (m, n) or not np.all((labels == 1) | (labels == -1)):
                raise ValueError(f"approach: expected ({m}, {n}) labels +1 or -1")
            approach = labels.astype(np.int8)
            approach.setflags(write=False)
            object.__setattr__(self, "approach", approach)

    def value(self, name: str) -> Array:
        """The numeric column ``name``, shape (m, ...), SI.

        Raises:
            ValueError: naming the kind, if these measurements have no such column.
        """
        if name not in self.values:
            raise ValueError(f"{self.kind} measurements hold no {name}")
        return self.values[name]

    def index(self, name: str) -> NDArray[np.intp]:
        """Each row's index into the labels ``name``, shape (m,); zeros without them (one
        port, one place)."""
        labels = self.labels.get(name)
        return labels.indices if labels is not None else np.zeros(len(self), dtype=np.intp)

    def names(self, name: str) -> tuple[str, ...]:
        """The names of the labels ``name`` (empty without them, or when unnamed)."""
        labels = self.labels.get(name)
        return labels.names if labels is not None else ()

    def __len__(self) -> int:
        return int(self.q_rad.shape[0])

    def subset(self, rows: ArrayLike) -> Measurements:
        """The measurements at the given row indices (every column, the label names whole)."""
        index = np.asarray(rows, dtype=np.intp)
        return Measurements(
            self.q_rad[index], self.kind,
            {name: column[index] for name, column in self.values.items()},
            {name: Labels(labels.names, labels.indices[index])
             for name, labels in self.labels.items()},
            None if self.approach is None else self.approach[index])


def joined(first: Measurements, second: Measurements) -> Measurements:
    """The rows of two measurement sets of one kind, the first's then the second's: the
    columns both have, the labels by the first's names (both index them: subsets of one set)."""
    approach = None if first.approach is None or second.approach is None \
        else np.concatenate([first.approach, second.approach])
    return Measurements(
        np.concatenate([first.q_rad, second.q_rad]), first.kind,
        {name: np.concatenate([column, second.values[name]])
         for name, column in first.values.items() if name in second.values},
        {name: Labels(labels.names, np.concatenate([labels.indices, second.index(name)]))
         for name, labels in first.labels.items()}, approach)


def approach_directions(q_rad: ArrayLike, start_rad: ArrayLike | None = None) -> NDArray[np.int8]:
    """The direction each joint last moved in when the poses are visited in order.

    Args:
        q_rad: Poses in visiting order, shape (m, n), rad.
        start_rad: Where the arm starts, shape (n,), rad; zeros (home) by default.

    Returns:
        +1 or −1 per joint and pose, shape (m, n); a joint that does not move keeps the
        direction it had (+1 before its first move).
    """
    q = np.asarray(q_rad, dtype=np.float64)
    start = np.zeros(q.shape[1]) if start_rad is None else np.asarray(start_rad, dtype=np.float64)
    steps = np.sign(np.diff(np.vstack([start, q]), axis=0))
    # Carry the last nonzero sign forward over joints that did not move.
    index = np.where(steps != 0, np.arange(len(q))[:, None], -1)
    last = np.maximum.accumulate(index, axis=0)
    signs = np.take_along_axis(steps, np.maximum(last, 0), axis=0)
    return np.where(last >= 0, signs, 1.0).astype(np.int8)
