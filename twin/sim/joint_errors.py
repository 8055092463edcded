"""Joint-level errors: the joint is not exactly at the angle the controller records.

Two sources, both in the gearbox, both invisible to a D-H model:

- a periodic transmission error ``A_j sin(h_j q_j + φ_j)`` (h_j cycles per joint revolution;
  arc-seconds to arc-minutes on real reducers);
- backlash: the joint stops half its lash ``b_j / 2`` short of or past the commanded angle,
  depending on the direction it last moved in (``approach`` = +1 or −1).

The actual angle is ``q + A sin(h q + φ) + (b / 2) · approach``; the recorded one is q.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import frozen_array

Array = NDArray[np.float64]


@dataclass(frozen=True)
class JointErrors:
    """Transmission error and backlash of each joint.

    Attributes:
        transmission_rad: Amplitude A of the periodic transmission error, shape (n,), rad.
        harmonic: Cycles per joint revolution h, shape (n,), integers >= 1 (stored as float).
        phase_rad: Phase φ, shape (n,), rad.
        backlash_rad: Full lash b, shape (n,), rad.
    """

    transmission_rad: Array
    harmonic: Array
    phase_rad: Array
    backlash_rad: Array

    def __post_init__(self) -> None:
        n = np.asarray(self.transmission_rad).shape[-1]
        for name in ("transmission_rad", "harmonic", "phase_rad", "backlash_rad"):
            value = frozen_array(getattr(self, name), (n,), name, broadcast=True)
            object.__setattr__(self, name, value)
        if np.any(self.transmission_rad < 0) or np.any(self.backlash_rad < 0):
            raise ValueError("amplitudes and backlash must be >= 0")
        if np.any(self.harmonic < 1) or np.any(self.harmonic != np.round(self.harmonic)):
            raise ValueError("harmonic: expected integers >= 1")

    @classmethod
    def none(cls, n: int) -> JointErrors:
        """No joint-level errors on n joints."""
        zeros = np.zeros(n)
        return cls(zeros, np.ones(n), zeros, zeros)

    @property
    def active(self) -> bool:
        """Whether any error is nonzero."""
        return bool(np.any(self.transmission_rad) or np.any(self.backlash_rad))

    def actual(self, q_rad: ArrayLike, approach: ArrayLike) -> Array:
        """The joint angles the arm is really at.

        Args:
            q_rad: Recorded (commanded) joint angles, shape (m, n), rad.
            approach: Direction each joint last moved in, shape (m, n), +1 or −1.

        Returns:
            Actual joint angles, shape (m, n), rad.
        """
        q = np.asarray(q_rad, dtype=np.float64)
        periodic = self.transmission_rad * np.sin(self.harmonic * q + self.phase_rad)
        return q + periodic + 0.5 * self.backlash_rad * np.asarray(approach, dtype=np.float64)


def approach_directions(q_rad: ArrayLike, start_rad: ArrayLike | None = None) -> Array:
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
    return np.where(last >= 0, signs, 1.0)
