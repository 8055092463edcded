"""Random table errors: how far the true robot is from its nominal table.

Each of the 4n parameters gets an independent draw: uniform in ±scale, or normal with σ = scale,
where the scale is given per parameter kind (a, d in m; α, θ and a Hayati joint's β in rad) and
optionally per joint. Draws are clipped to the box the scenario's calibration searches — the
paper's ±5 mm / ±8° unless its ``[calibration] bounds`` say otherwise — so that the truth is
always inside it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from twin.arrays import Array, frozen_array
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
        box: The search box the draws are clipped to, (lower, upper), each (4, n), m and rad;
            the paper's ±5 mm / ±8° if None.
    """

    distribution: str
    scale: Array
    is_length: NDArray[np.bool_] | None = None
    box: tuple[Array, Array] | None = None

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
        bound = np.where(lengths, DH_BOUND_M, DH_BOUND_RAD)
        lower, upper = (-bound, bound) if self.box is None else self.box
        object.__setattr__(self, "box", (frozen_array(lower, scale.shape, "box"),
                                         frozen_array(upper, scale.shape, "box")))

    def draw(self, rng: np.random.Generator) -> Array:
        """One table of errors, shape (4, n), m and rad, inside the search box."""
        unit = rng.uniform(-1.0, 1.0, self.scale.shape) if self.distribution == "uniform" \
            else rng.normal(0.0, 1.0, self.scale.shape)
        assert self.box is not None  # set in __post_init__
        return np.asarray(np.clip(unit * self.scale, *self.box), dtype=np.float64)
