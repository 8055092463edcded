"""Joint-level errors: transmission error and direction-dependent backlash."""

from __future__ import annotations

import numpy as np
import pytest

from twin.dataset import approach_directions
from twin.scenario import JointErrors


def test_approach_directions_follow_the_motion() -> None:
    """Each joint's direction is the sign of its last move; a joint that stays keeps it."""
    q = np.array([[0.1, 0.0], [0.05, 0.0], [0.05, -0.2], [0.3, -0.2]])
    expected = np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]])
    assert np.array_equal(approach_directions(q), expected)
    assert np.array_equal(approach_directions(q[:1], start_rad=[0.2, 0.0]), [[-1, 1]])


def test_backlash_and_transmission_error() -> None:
    """The joint lags or leads by half the lash, plus A·sin(h q + φ)."""
    errors = JointErrors(transmission_rad=np.array([1e-3, 0.0]), harmonic=np.array([2, 1]),
                         phase_rad=np.array([0.5, 0.0]), backlash_rad=np.array([0.0, 4e-4]))
    q = np.array([[0.3, 0.7], [1.1, -0.4]])
    approach = np.array([[1.0, 1.0], [-1.0, -1.0]])
    actual = errors.actual(q, approach)
    assert actual[:, 0] == pytest.approx(q[:, 0] + 1e-3 * np.sin(2 * q[:, 0] + 0.5))
    assert actual[:, 1] == pytest.approx(q[:, 1] + np.array([2e-4, -2e-4]))
    assert errors.active and not JointErrors.none(2).active


def test_invalid_joint_errors_are_rejected() -> None:
    """Negative amplitudes and fractional harmonics are errors."""
    with pytest.raises(ValueError):
        JointErrors(np.array([-1.0]), np.array([1]), np.array([0.0]), np.array([0.0]))
    with pytest.raises(ValueError):
        JointErrors(np.array([1.0]), np.array([1.5]), np.array([0.0]), np.array([0.0]))
