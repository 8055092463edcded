"""A warm-up during the capture: the arm's links grow with a temperature ramp.

The capture visits its poses at a fixed pace (``seconds_per_pose``); the arm's temperature rises
linearly from ``start_c`` by ``ramp_k`` over the capture, and each link's length entries (a_i
and d_i of a D-H table; a Hayati joint's β is an angle and does not grow) grow by their
expansion per kelvin times the rise since the start::

    a_i(T) = a_i + k_a,i · (T − start_c),   d_i(T) = d_i + k_d,i · (T − start_c)

The twin builds its MuJoCo model of each row's grown robot and measures that row on it
(:mod:`twin.sim.simulate`). Every ``reference_every`` poses the capture revisits its first pose,
a reference the drift test reads (:mod:`twin.analysis.drift`). Steel grows 11.5 µm/(m·K),
aluminium 23: a 0.3 m aluminium link some 7 µm/K.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from twin.arrays import Array, frozen_array
from twin.dataset import reference_visits

REFERENCE_RTOL_RAD = 1e-12
"""Recorded angles this close (rad) to the first pose's mark a revisit of it."""


@dataclass(frozen=True)
class Thermal:
    """How the arm warms up during a capture (module docstring).

    Attributes:
        expansion_m_per_k: Growth of each length entry of the table per kelvin, shape (2, n):
            rows a and d (a Hayati joint's second row, β, must be 0), m/K.
        start_c: The arm's temperature at the first pose, °C.
        ramp_k: Its rise over the capture, K (0: none; the temperatures are still written).
        seconds_per_pose: The time from one pose to the next, s (> 0).
        reference_every: Revisit the first pose after every this many poses (0: never).
    """

    expansion_m_per_k: Array
    start_c: float = 20.0
    ramp_k: float = 0.0
    seconds_per_pose: float = 30.0
    reference_every: int = 0

    def __post_init__(self) -> None:
        expansion = np.asarray(self.expansion_m_per_k, dtype=np.float64)
        object.__setattr__(self, "expansion_m_per_k",
                           frozen_array(expansion, (2, expansion.shape[-1]), "expansion_m_per_k"))
        if not self.seconds_per_pose > 0:
            raise ValueError("seconds_per_pose: expected > 0")
        if self.reference_every < 0:
            raise ValueError("reference_every: expected >= 0")

    def visits(self, count: int) -> NDArray[np.intp]:
        """The order a capture of ``count`` poses visits them in, with the first pose revisited
        after every ``reference_every`` (and at the end): indices into the poses, shape
        (≥ count,)."""
        return reference_visits(count, self.reference_every)

    def times_s(self, rows: int) -> Array:
        """Each row's time since the capture started, shape (rows,), s."""
        return np.arange(rows, dtype=np.float64) * self.seconds_per_pose

    def temperatures_c(self, rows: int) -> Array:
        """Each row's temperature, shape (rows,), °C: the ramp from the start to the last row."""
        share = np.arange(rows, dtype=np.float64) / max(rows - 1, 1)
        return self.start_c + self.ramp_k * share

    def growth(self, temperature_c: float) -> Array:
        """How far the table's entries have grown at a temperature, shape (4, n), m (angles 0)."""
        n = self.expansion_m_per_k.shape[1]
        growth = np.zeros((4, n))
        growth[:2] = self.expansion_m_per_k * (temperature_c - self.start_c)
        return growth
