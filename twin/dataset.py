"""Measurements: joint angles and what an instrument read at each pose.

One row per pose. What was read decides the measurement kind (:mod:`twin.kinds`):

- ``length``: a cable length from a port to the measured point (drawstring encoder), with the
  port of each row when the encoder was moved between several ports;
- ``position``: the measured point's 3-D position in an instrument frame (laser tracker);
- ``point``: nothing but the name of an unknown fixed place the measured point was brought to
  (a ball in a socket, a pointer on a mark).

Optionally, the direction each joint last moved in before the reading (``approach``, ±1), which
backlash depends on.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import Array, frozen_array


def _index(values: ArrayLike | None, m: int, what: str) -> NDArray[np.intp] | None:
    if values is None:
        return None
    array = np.asarray(values)
    if array.shape != (m,) or (array.size and (not np.issubdtype(array.dtype, np.integer)
                                               or array.min() < 0)):
        raise ValueError(f"{what}: expected {m} non-negative integers, got {array.shape}")
    index = np.array(array, dtype=np.intp)
    index.setflags(write=False)
    return index


@dataclass(frozen=True)
class Measurements:
    """Joint angles and readings, one row per pose; exactly one of ``length_m``,
    ``position_m``, ``point`` is given.

    Attributes:
        q_rad: Recorded joint angles, shape (m, n), rad.
        length_m: Cable lengths, shape (m,), m.
        position_m: Measured point positions in the instrument's frame, shape (m, 3), m.
        point: Index of the fixed place each row's measured point was at, shape (m,).
        port: Index of the port each row's cable ran from, shape (m,); None: one port.
        port_names: The name of each port index, when the data name their ports (a ``port``
            column); the calibration matches them to the rig's ports by name.
        point_names: The name of each fixed place index (a ``point`` column).
        approach: Direction each joint last moved in before the reading, shape (m, n), +1 or
            −1 (int8 labels); None when not recorded.
    """

    q_rad: Array
    length_m: Array | None = None
    position_m: Array | None = None
    point: NDArray[np.intp] | None = None
    port: NDArray[np.intp] | None = None
    approach: NDArray[np.int8] | None = None
    port_names: tuple[str, ...] = ()
    point_names: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        q = np.asarray(self.q_rad, dtype=np.float64)
        if q.ndim != 2:
            raise ValueError(f"q_rad: shape {q.shape}, expected (m, n)")
        m, n = q.shape
        object.__setattr__(self, "q_rad", frozen_array(q, (m, n), "q_rad"))
        given = [name for name in ("length_m", "position_m", "point")
                 if getattr(self, name) is not None]
        if len(given) != 1:
            raise ValueError(f"measurements: expected exactly one of length_m, position_m, "
                             f"point, got {given or 'none'}")
        if self.length_m is not None:
            object.__setattr__(self, "length_m", frozen_array(self.length_m, (m,), "length_m"))
        if self.position_m is not None:
            object.__setattr__(self, "position_m",
                               frozen_array(self.position_m, (m, 3), "position_m"))
        object.__setattr__(self, "point", _index(self.point, m, "point"))
        object.__setattr__(self, "port", _index(self.port, m, "port"))
        if self.port is not None and self.length_m is None:
            raise ValueError("port: only cable lengths have ports")
        for index, names, what in ((self.port, self.port_names, "port"),
                                   (self.point, self.point_names, "point")):
            object.__setattr__(self, f"{what}_names", tuple(names))
            if names and (index is None or (index.size and index.max() >= len(names))):
                raise ValueError(f"{what}_names: {len(names)} names for the {what} indices")
        if self.approach is not None:
            labels = np.asarray(self.approach)
            # Labels, not measured values: each must be one of the two directions exactly.
            if labels.shape != (m, n) or not np.all(np.isin(labels, (-1, 1))):
                raise ValueError(f"approach: expected ({m}, {n}) labels +1 or -1")
            approach = labels.astype(np.int8)
            approach.setflags(write=False)
            object.__setattr__(self, "approach", approach)

    @property
    def kind(self) -> str:
        """``"length"``, ``"position"`` or ``"point"``."""
        if self.length_m is not None:
            return "length"
        return "position" if self.position_m is not None else "point"

    @property
    def lengths(self) -> Array:
        """The cable lengths, shape (m,), m.

        Raises:
            ValueError: if these measurements are not cable lengths.
        """
        if self.length_m is None:
            raise ValueError(f"{self.kind} measurements hold no cable lengths")
        return self.length_m

    @property
    def port_index(self) -> NDArray[np.intp]:
        """The port of each row, shape (m,); zeros when there is one port."""
        return self.port if self.port is not None else np.zeros(len(self), dtype=np.intp)

    def __len__(self) -> int:
        return int(self.q_rad.shape[0])

    def subset(self, rows: ArrayLike) -> Measurements:
        """The measurements at the given row indices."""
        index = np.asarray(rows, dtype=np.intp)

        def pick(values: NDArray | None) -> NDArray | None:
            return None if values is None else values[index]

        return Measurements(self.q_rad[index], pick(self.length_m), pick(self.position_m),
                            pick(self.point), pick(self.port), pick(self.approach),
                            self.port_names, self.point_names)


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
