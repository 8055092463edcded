"""Measurement noise of the drawstring encoder and the arm's repeatability.

The encoder reads ``round(((1 + s) L + c + e + o) / res) · res`` with L the true length, s its
scale error (a drum or a count per millimetre off by s: every extension reads that much too
long), c an unknown constant offset (the encoder's zero), e ~ N(0, σ²), o an outlier (with
probability ``rate``, a random sign times U(0.5, 1.5) · ``outlier``, else 0), res the
resolution.

Repeatability is the arm's: each pose's joints land N(0, σ_q²) off their target, with one σ_q
for all joints chosen so that the RMS flange displacement over the poses is ``repeatability``.

The joint angles a controller reports may be rounded (``joint_resolution``, a log written to
0.1°): the recorded angle is the target rounded to the resolution, the arm stands at the
target (and its jitter) — the calibration reads angles up to half a step off.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import Array
from twin.geometry.kinematics import point_jacobian
from twin.robot import RobotModel
from twin.units import MICRO, m_to_mm, rad_to_deg
from twin.unknowns.scale import BOUND as MAX_SCALE


class Readings(NamedTuple):
    """What the encoder reports."""

    length_m: Array
    """Readings, shape (m,), m."""
    outlier_rows: NDArray[np.intp]
    """Rows that received an outlier, shape (k,)."""


@dataclass(frozen=True)
class NoiseModel:
    """Noise of one simulated capture (all SI).

    Attributes:
        sigma_m: Gaussian length noise 1σ, m.
        resolution_m: Encoder resolution, m (0: no quantisation).
        repeatability_m: RMS flange displacement from joint jitter, m (0: none).
        outlier_rate: Probability of an outlier per reading, in [0, 1].
        outlier_m: Typical outlier size, m.
        offset_m: Constant length offset the calibration is not told, m.
        scale: The encoder's scale error s the calibration is not told, m/m (1e-4: 100 ppm),
            within ±:data:`MAX_SCALE`.
        joint_resolution_rad: The resolution the joint angles are recorded to, one for every
            joint or one per joint, rad (empty or 0: exact); a prismatic joint's travel is
            recorded exactly (its entry 0, :func:`twin.scenario.reader` sees to it).
    """

    sigma_m: float = 0.0
    resolution_m: float = 0.0
    repeatability_m: float = 0.0
    outlier_rate: float = 0.0
    outlier_m: float = 0.0
    offset_m: float = 0.0
    scale: float = 0.0
    joint_resolution_rad: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        for name in ("sigma_m", "resolution_m", "repeatability_m", "outlier_m"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"{name}: expected a finite value >= 0, got {value}")
        if not 0.0 <= self.outlier_rate <= 1.0:
            raise ValueError(f"outlier_rate: expected [0, 1], got {self.outlier_rate}")
        if not np.isfinite(self.offset_m):
            raise ValueError("offset_m: expected a finite value")
        if not (np.isfinite(self.scale) and abs(self.scale) <= MAX_SCALE):
            raise ValueError(f"scale: expected a finite value within ±{MAX_SCALE:g}, got "
                             f"{self.scale}")
        resolution = tuple(float(v) for v in np.ravel(self.joint_resolution_rad))
        if not all(np.isfinite(v) and v >= 0 for v in resolution):
            raise ValueError("joint_resolution_rad: expected finite values >= 0")
        object.__setattr__(self, "joint_resolution_rad", resolution)

    def recorded(self, q_rad: ArrayLike) -> Array:
        """The joint angles as recorded: rounded to the resolution, shape (m, n), rad."""
        q = np.asarray(q_rad, dtype=np.float64)
        step = np.zeros(q.shape[-1]) + np.asarray(self.joint_resolution_rad or (0.0,))
        safe = np.where(step > 0, step, 1.0)
        return np.asarray(np.where(step > 0, np.round(q / safe) * safe, q), dtype=np.float64)

    @property
    def encoder_sigma_m(self) -> float:
        """The encoder's noise 1σ with its resolution folded in (res²/12), m."""
        return float(np.hypot(self.sigma_m, self.resolution_m / np.sqrt(12.0)))

    def joint_sigma_rad(self, robot: RobotModel, q_rad: ArrayLike) -> float:
        """σ_q that gives an RMS flange displacement of ``repeatability_m`` at these poses, rad.

        Args:
            robot: The arm.
            q_rad: Poses, shape (m, n), rad.
        """
        if self.repeatability_m <= 0.0:
            return 0.0
        joint_jacobian = point_jacobian(robot.structure, robot.dh, q_rad).joints
        mean_square_gain = float(np.mean(np.sum(joint_jacobian**2, axis=(1, 2))))
        return self.repeatability_m / float(np.sqrt(mean_square_gain))

    def read(self, length_m: ArrayLike, rng: np.random.Generator) -> Readings:
        """Encoder readings of true lengths (draws noise, then outliers, from ``rng``)."""
        true = np.asarray(length_m, dtype=np.float64)
        reading = ((1.0 + self.scale) * true + self.offset_m
                   + rng.normal(0.0, 1.0, true.shape) * self.sigma_m)
        is_outlier = rng.random(true.shape) < self.outlier_rate
        size = rng.uniform(0.5, 1.5, true.shape) * rng.choice([-1.0, 1.0], true.shape)
        reading = reading + np.where(is_outlier, size * self.outlier_m, 0.0)
        if self.resolution_m > 0:
            reading = np.round(reading / self.resolution_m) * self.resolution_m
        return Readings(reading, np.flatnonzero(is_outlier))

    def to_dict(self) -> dict[str, float]:
        """The JSON form written to truth.json (mm)."""
        return {
            "sigma_mm": float(m_to_mm(self.sigma_m)),
            "resolution_mm": float(m_to_mm(self.resolution_m)),
            "repeatability_mm": float(m_to_mm(self.repeatability_m)),
            "outlier_rate": self.outlier_rate,
            "outlier_mm": float(m_to_mm(self.outlier_m)),
            "offset_mm": float(m_to_mm(self.offset_m)),
            "scale_ppm": self.scale * MICRO,
            "joint_resolution_deg": rad_to_deg(self.joint_resolution_rad).tolist(),
        }
