"""Encoder noise, quantisation, outliers, offset, and the arm's repeatability."""

from __future__ import annotations

import numpy as np
import pytest

from twin.io.robot_file import default_robot
from twin.robot import random_poses
from twin.scenario import NoiseModel


def test_readings_are_quantised_to_the_resolution() -> None:
    """Every reading is a whole number of resolution steps from zero."""
    noise = NoiseModel(sigma_m=2e-6, resolution_m=4e-6)
    readings = noise.read(np.random.default_rng(0).uniform(0.2, 1.2, 500),
                          np.random.default_rng(1))
    steps = readings.length_m / 4e-6
    assert np.max(np.abs(steps - np.round(steps))) < 1e-6


def test_gaussian_noise_and_offset() -> None:
    """Readings minus the truth have the offset as mean and σ as standard deviation."""
    truth = np.full(20000, 0.8)
    noise = NoiseModel(sigma_m=1e-5, offset_m=3e-3)
    error = noise.read(truth, np.random.default_rng(2)).length_m - truth
    assert np.mean(error) == pytest.approx(3e-3, abs=3e-7)
    assert np.std(error) == pytest.approx(1e-5, rel=0.03)


def test_outliers_have_the_rate_and_size_asked_for() -> None:
    """About ``rate`` of the readings carry a gross error of 0.5–1.5 × the outlier size, and
    exactly those rows are reported."""
    truth = np.full(10000, 0.8)
    noise = NoiseModel(outlier_rate=0.05, outlier_m=1e-3)
    readings = noise.read(truth, np.random.default_rng(3))
    error = np.abs(readings.length_m - truth)
    assert np.array_equal(np.flatnonzero(error > 0), readings.outlier_rows)
    assert readings.outlier_rows.size / truth.size == pytest.approx(0.05, abs=0.006)
    sizes = error[readings.outlier_rows]
    assert np.all((sizes >= 0.5e-3) & (sizes <= 1.5e-3))


def test_repeatability_is_the_rms_flange_jitter() -> None:
    """Joint jitter of the returned σ moves the flange by ``repeatability`` RMS."""
    robot = default_robot()
    rng = np.random.default_rng(4)
    q = random_poses(robot, 400, rng)
    noise = NoiseModel(repeatability_m=1e-5)
    sigma = noise.joint_sigma_rad(robot, q)
    q = np.tile(q, (50, 1))
    jitter = rng.normal(0.0, sigma, q.shape)
    shift = robot.flange_positions(q + jitter) - robot.flange_positions(q)
    assert np.sqrt(np.mean(np.sum(shift**2, axis=-1))) == pytest.approx(1e-5, rel=0.03)
    assert NoiseModel().joint_sigma_rad(robot, q) == 0.0
