"""Cable data computed by the core's own model: for tests, benchmarks and quick examples.

The MuJoCo twin (:mod:`twin.sim`) produces data from an independent physical model; this
module is the closed-form counterpart, where the truth is exactly the model being fitted.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from twin.dataset import Measurements
from twin.kinds.length import cable_length, length_measurements
from twin.robot import RobotModel


def synthesize(
    robot: RobotModel,
    q_rad: ArrayLike,
    port_m: ArrayLike,
    sigma_m: float,
    rng: np.random.Generator,
) -> Measurements:
    """Cable lengths of ``robot`` at the poses, with Gaussian noise of σ = ``sigma_m`` (m)."""
    q_rad = np.asarray(q_rad, dtype=np.float64)
    length_m = cable_length(robot.structure, robot.dh, q_rad, port_m)
    return length_measurements(q_rad, length_m + rng.normal(0.0, sigma_m, size=length_m.shape))
