"""Regenerate `measurements.csv`: 120 poses of an IRB 120 with a fixed, known perturbation.

Made by the calibration core's own cable model (not the MuJoCo twin), so the truth below is
exactly what LM should find on the identifiable combinations. Run from the repository root:
``python examples/irb120_lm/generate.py``.
"""

from pathlib import Path

import numpy as np

from twin.io.measurements import write_measurements
from twin.io.robot_file import default_robot
from twin.robot import random_poses
from twin.synthetic import synthesize
from twin.units import dh_rows_from_display, mm_to_m

TRUE_DELTA = {  # mm and degrees
    "a": [0.5, -0.8, 0.6, 0.3, -0.4, 0.2],
    "d": [0.7, 0.4, -0.6, 0.5, 0.3, -0.5],
    "alpha": [0.1, -0.2, 0.15, -0.1, 0.2, 0.1],
    "theta": [0.2, 0.1, -0.15, 0.1, -0.2, 0.05],
}
PORT_MM = [600.0, -400.0, 100.0]
SIGMA_MM = 0.01
SEED = 1


def main() -> None:
    robot = default_robot()
    rng = np.random.default_rng(SEED)
    true_robot = robot.perturbed(dh_rows_from_display(TRUE_DELTA).ravel())
    q_rad = random_poses(robot, 120, rng)
    data = synthesize(true_robot, q_rad, mm_to_m(PORT_MM), float(mm_to_m(SIGMA_MM)), rng)
    write_measurements(Path(__file__).with_name("measurements.csv"), data)


if __name__ == "__main__":
    main()
