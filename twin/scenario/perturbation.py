"""Random table errors: how far the true robot is from its nominal table.

Each of the 4n parameters gets an independent draw: uniform in ±scale, or normal with σ = scale,
where the scale is given per parameter kind (a, d in m; α, θ and a Hayati joint's β in rad) and
optionally per joint. The paper's search bounds are ±5 mm / ±8°; draws are clipped to them (by
each entry's unit) so that the truth is always inside the box every method searches.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from twin.arrays import Array
from twin.units import DH_IS_LENGTH
from twin.unknowns.dh import BOUND_M as DH_BOUND_M
from twin.unknowns.dh import BOUND_RAD as DH_BOUND_RAD

DISTRIBUTIONS = ("uniform", "normal")


@dataclass(frozen=True)
class Perturbation:
    """How the true D-H errors are drawn.

    Attributes:
        distribution: ``"uniform"`` (±scale) or ``"normal"`` (σ = scale).
        scale: Scale per parameter, shape (4, n): rows a [m], d [m] (β [rad] on a Hayati
            joint), α [rad], θ [rad].
        is_length: Which entries are lengths, shape (4, n) (the robot's
            :attr:`~twin.robot.RobotModel.is_length`); D-H's rows if None.
    """

    distribution: str
    scale: Array
    is_length: NDArray[np.bool_] | None = None

    def __post_init__(self) -> None:
        if self.distribution not in DISTRIBUTIONS:
            raise ValueError(f"distribution {self.distribution!r}: expected one of {DISTRIBUTIONS}")
        scale = np.array(self.scale, dtype=np.float64)
        if scale.ndim != 2 or scale.shape[0] != 4:
            raise ValueError(f"scale: shape {scale.shape}, expected (4, n)")
        if not np.all(np.isfinite(scale)) or np.any(scale < 0):
            raise ValueError("scale: expected finite values >= 0")
        scale.setflags(write=False)
        object.__setattr__(self, "scale", scale)
        lengths = np.broadcast_to(np.array(DH_IS_LENGTH)[:, None], scale.shape) \
            if self.is_length is None else np.array(self.is_length, dtype=bool)
        if lengths.shape != scale.shape:
            raise ValueError(f"is_length: shape {lengths.shape}, expected {scale.shape}")
        object.__setattr__(self, "is_length", lengths)

    def draw(self, rng: np.random.Generator) -> Array:
        """One table of errors, shape (4, n), m and rad, inside the paper's search bounds."""
        unit = rng.uniform(-1.0, 1.0, self.scale.shape) if self.distribution == "uniform" \
            else rng.normal(0.0, 1.0, self.scale.shape)
        assert self.is_length is not None  # set in __post_init__
        bound = np.where(self.is_length, DH_BOUND_M, DH_BOUND_RAD)
        return np.asarray(np.clip(unit * self.scale, -bound, bound), dtype=np.float64)
