"""Cable lengths, residuals and the cable Jacobian with optional port and offset unknowns."""

from __future__ import annotations

import numpy as np
import pytest

from twin.cable import CableModel, Measurements, cable_length
from twin.kinematics import flange_position
from twin.robot import RobotModel


def test_length_is_distance_port_to_flange(irb120: RobotModel, port_m: np.ndarray) -> None:
    """ℓ = ‖P − P_E‖ (paper eq. 1) at the home pose."""
    q = np.zeros((1, 6))
    expected = np.linalg.norm(np.array([0.374, 0.0, 0.630]) - port_m)
    assert cable_length(irb120.dh, q, port_m)[0] == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize(("port", "offset"), [(False, False), (True, False), (False, True),
                                              (True, True)])
def test_jacobian_matches_finite_differences(
    irb120: RobotModel, measurements: Measurements, port_m: np.ndarray, port: bool, offset: bool
) -> None:
    """∂r/∂x equals central differences for every unknown layout."""
    model = CableModel(irb120.dh, port_m, estimate_port=port, estimate_offset=offset)
    rng = np.random.default_rng(3)
    x = rng.normal(scale=1e-3, size=model.n_params)
    data = measurements.subset(np.arange(15))
    r, jacobian = model.jacobian(x, data)
    np.testing.assert_allclose(r, model.residuals(x, data), atol=1e-15)
    eps = 1e-6
    steps = np.eye(model.n_params) * eps
    numeric = (model.residuals(x + steps, data) - model.residuals(x - steps, data)).T / (2 * eps)
    np.testing.assert_allclose(jacobian, numeric, atol=1e-8)


def test_unknown_layout(irb120: RobotModel, port_m: np.ndarray) -> None:
    """Names and bounds follow eq. 7's order, then port, then offset."""
    model = CableModel(irb120.dh, port_m, estimate_port=True, estimate_offset=True)
    assert model.n_params == 28
    assert model.names[:2] == ("a1", "a2") and model.names[-4:] == (
        "port_x", "port_y", "port_z", "offset")
    lower, upper = model.bounds()
    np.testing.assert_allclose(upper[:12], 5e-3)
    np.testing.assert_allclose(upper[12:24], np.deg2rad(8.0))
    np.testing.assert_array_equal(lower, -upper)


def test_batched_residuals(
    irb120: RobotModel, measurements: Measurements, port_m: np.ndarray
) -> None:
    """Residuals of K candidates in one call equal K single calls."""
    model = CableModel(irb120.dh, port_m, estimate_offset=True)
    x = np.random.default_rng(4).normal(scale=1e-3, size=(5, model.n_params))
    batched = model.residuals(x, measurements)
    for k in range(5):
        np.testing.assert_allclose(batched[k], model.residuals(x[k], measurements), atol=1e-15)


def test_offset_adds_to_every_length(
    irb120: RobotModel, measurements: Measurements, port_m: np.ndarray
) -> None:
    """The offset unknown shifts every model length by its value."""
    model = CableModel(irb120.dh, port_m, estimate_offset=True)
    x = np.zeros(25)
    x[-1] = 0.002
    plain = np.linalg.norm(flange_position(irb120.dh, measurements.q_rad) - port_m, axis=-1)
    np.testing.assert_allclose(model.lengths(x, measurements.q_rad), plain + 0.002, atol=1e-15)
