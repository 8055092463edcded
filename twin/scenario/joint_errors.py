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
from numpy.typing import ArrayLike

from twin.arrays import Array, frozen_array


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

    def coefficients(self) -> Array:
        """The transmission error in the calibration's terms: per joint the coefficients of
        sin q, cos q, sin 2q, cos 2q (:mod:`twin.unknowns.transmission`), shape (n, 4), rad;
        NaN for a joint whose error repeats more than twice per revolution (no first- or
        second-harmonic model holds it)."""
        amplitude, phase = self.transmission_rad, self.phase_rad
        terms = np.zeros((len(amplitude), 4))
        # A sin(h q + φ) = A cos φ · sin(h q) + A sin φ · cos(h q).
        harmonic = np.round(self.harmonic).astype(int)  # whole numbers (checked on creation)
        for h, columns in ((1, [0, 1]), (2, [2, 3])):
            rows = harmonic == h
            terms[np.ix_(rows, columns)] = np.stack(
                [amplitude[rows] * np.cos(phase[rows]), amplitude[rows] * np.sin(phase[rows])],
                axis=-1)
        terms[(harmonic > 2) & (amplitude > 0)] = np.nan
        return terms

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
