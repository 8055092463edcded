"""Shared fixtures: the IRB 120, a known perturbation and data made by the core's model."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from twin.cable import Measurements
from twin.io.measurements import write_measurements
from twin.robot import RobotModel, default_robot
from twin.synthetic import random_poses, synthesize
from twin.units import dh_rows_from_display, mm_to_m

PORT_M = mm_to_m([600.0, -400.0, 100.0])
TRUE_DELTA = dh_rows_from_display(
    {
        "a": [0.5, -0.8, 0.6, 0.3, -0.4, 0.2],
        "d": [0.7, 0.4, -0.6, 0.5, 0.3, -0.5],
        "alpha": [0.1, -0.2, 0.15, -0.1, 0.2, 0.1],
        "theta": [0.2, 0.1, -0.15, 0.1, -0.2, 0.05],
    }
)
"""A known perturbation, shape (4, 6), m and rad: about 1.3 mm RMSE on the cable."""


@pytest.fixture(scope="session")
def port_m() -> np.ndarray:
    """The encoder port of the core-made data, shape (3,), m."""
    return PORT_M


@pytest.fixture(scope="session")
def true_delta() -> np.ndarray:
    """The known perturbation of the core-made data, shape (4, 6), m and rad."""
    return TRUE_DELTA


@pytest.fixture(scope="session")
def irb120() -> RobotModel:
    return default_robot()


@pytest.fixture(scope="session")
def true_robot(irb120: RobotModel) -> RobotModel:
    return irb120.perturbed(TRUE_DELTA)


@pytest.fixture()
def csv_path(measurements: Measurements, tmp_path: Path) -> Path:
    """The core-made measurements written as a CSV file (degrees, mm)."""
    path = tmp_path / "measurements.csv"
    write_measurements(path, measurements)
    return path


@pytest.fixture(scope="session")
def measurements(irb120: RobotModel, true_robot: RobotModel) -> Measurements:
    """120 poses of the perturbed robot, σ = 0.01 mm, seeded."""
    rng = np.random.default_rng(7)
    return synthesize(true_robot, random_poses(irb120, 120, rng), PORT_M, 1e-5, rng)
