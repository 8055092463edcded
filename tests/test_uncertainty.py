"""Covariance, noise estimate, per-parameter σ and predicted flange accuracy."""

from __future__ import annotations

import numpy as np
import pytest

from twin.analysis.identifiability import measurement_identifiability
from twin.analysis.uncertainty import (
    base_covariance,
    flange_sigma,
    parameter_covariance,
    parameter_sigma,
    predicted_flange_rms,
    residual_sigma,
    rms_distance,
)
from twin.analysis.unseen import _sparse_names, unseen_directions, unseen_with_weak
from twin.calibration.pipeline import calibrate
from twin.calibration.settings import CalibrationSettings
from twin.calibration.setup import make_model
from twin.dataset import Measurements
from twin.kinds.length import length_measurements
from twin.rig import Rig
from twin.robot import RobotModel, random_poses

SIGMA_M = 1e-5


@pytest.fixture(scope="module")
def setup(irb120: RobotModel, port_m: np.ndarray):
    """Nominal model, 96 poses, their Jacobian and identifiability."""
    q = random_poses(irb120, 96, np.random.default_rng(11))
    data = length_measurements(q, np.ones(len(q)))
    model = make_model(irb120, Rig.cable(port_m))
    _, J = model.jacobian(np.zeros(24), data)
    return model, data, J, measurement_identifiability(model, np.zeros(24), data)


def test_base_covariance_matches_monte_carlo_scatter(setup) -> None:
    """The linearised base-parameter estimator's scatter over 4000 noise draws matches
    σ²(J_BᵀJ_B)⁻¹ within sampling error (diagonal within 10 %)."""
    _, _, J, ident = setup
    J_base = J[:, ident.base]
    noise = np.random.default_rng(5).normal(0.0, SIGMA_M, size=(4000, J.shape[0]))
    estimates = np.linalg.lstsq(J_base, noise.T, rcond=None)[0].T
    empirical = np.cov(estimates, rowvar=False)
    predicted = base_covariance(J, ident.base, SIGMA_M)[np.ix_(ident.base, ident.base)]
    np.testing.assert_allclose(np.diag(empirical), np.diag(predicted), rtol=0.1)


def test_base_and_pseudo_inverse_covariances_predict_the_same_flange_error(
    setup, irb120: RobotModel
) -> None:
    """Both are generalised inverses of JᵀJ and flange motions lie in J's row space, so the
    predicted flange error is the same for either — even though the parameter σ differ."""
    model, _, J, ident = setup
    q = random_poses(irb120, 300, np.random.default_rng(1))
    flange = model.flange_jacobian(np.zeros(24), model.poses(q))
    full = parameter_covariance(J, SIGMA_M)
    base = base_covariance(J, ident.base, SIGMA_M)
    assert not np.allclose(np.diag(full), np.diag(base), rtol=1e-3, atol=0.0)
    np.testing.assert_allclose(flange_sigma(flange, base), flange_sigma(flange, full), rtol=1e-6)
    assert predicted_flange_rms(flange, base) == pytest.approx(
        float(np.sqrt(np.mean(flange_sigma(flange, base) ** 2))))


def test_parameter_sigma_is_nan_for_dependent_unknowns(setup) -> None:
    """Only the base parameters have a standard deviation."""
    _, _, J, ident = setup
    sigma = parameter_sigma(base_covariance(J, ident.base, SIGMA_M), ident.base)
    assert np.all(np.isfinite(sigma[ident.base])) and np.all(sigma[ident.base] > 0)
    assert np.all(np.isnan(sigma[ident.dependent]))


def test_residual_sigma_divides_by_the_degrees_of_freedom() -> None:
    """σ̂² = ‖r‖²/(m − rank); no degree of freedom left is an error."""
    assert residual_sigma(np.array([3.0, 4.0, 0.0]), 2) == pytest.approx(5.0)
    with pytest.raises(ValueError):
        residual_sigma(np.ones(3), 3)


def test_calibration_carries_covariance_and_an_honest_accuracy(
    irb120: RobotModel, true_robot: RobotModel, measurements: Measurements, port_m: np.ndarray,
    true_delta: np.ndarray,
) -> None:
    """lm-base on 120 poses at σ = 0.01 mm: the noise estimate is near 0.01 mm, the predicted
    flange accuracy is within a factor of 3 of the true flange error over the workspace, and
    every unknown's true error lies within 5 σ of its estimate, the truth held along the
    unseen directions as the estimate is."""
    result = calibrate(irb120, measurements, port_m, method="lm-base",
                       settings=CalibrationSettings())
    uncertainty = result.uncertainty
    assert uncertainty is not None and result.identifiability is not None
    assert 0.7 * SIGMA_M < uncertainty.noise_sigma_m < 1.4 * SIGMA_M
    q = random_poses(irb120, 500, np.random.default_rng(2))
    true_error = rms_distance(result.identified_geometry.flange_positions(q),
                              true_robot.flange_positions(q))
    assert uncertainty.flange_rms_m / 3 < true_error < 3 * uncertainty.flange_rms_m
    assert uncertainty.covariance.shape == (24, 24)
    unseen = result.unseen
    assert unseen is not None
    names = result.model.names
    held_entirely = np.isnan(uncertainty.sigma)
    assert "alpha6" in {names[i] for i in np.flatnonzero(held_entirely)}
    # The truth with its components along the unseen directions removed, as the calibration
    # holds them: that is what the estimate and its σ refer to.
    held_truth = unseen.remove(true_delta.ravel())
    seen = ~held_entirely
    z = (result.solver.x - held_truth)[seen] / uncertainty.sigma[seen]
    assert np.max(np.abs(z)) < 5.0, z


def test_unseen_with_and_without_the_start_share_one_factorisation(
        irb120: RobotModel, port_m: np.ndarray, true_delta: np.ndarray) -> None:
    """:func:`unseen_with_weak` gives what :func:`unseen_directions` gives without and with the
    start: with noise, where the start's test holds weak directions the other does not, and
    without, where it holds nothing more; unnamed, the same subspace."""
    q = random_poses(irb120, 60, np.random.default_rng(4))
    data = length_measurements(q, np.ones(len(q)))
    model = make_model(irb120, Rig.cable(port_m))
    nominal = measurement_identifiability(model, np.zeros(24), data)
    x, start, scale = true_delta.ravel(), np.zeros(24), model.scale()
    extra = []
    for noise in (SIGMA_M, 0.0):
        pair = unseen_with_weak(model, x, data, noise, scale, nominal, None, start)
        alone = (unseen_directions(model, x, data, noise, scale, nominal),
                 unseen_directions(model, x, data, noise, scale, nominal, start=start))
        for shared, own in zip(pair, alone, strict=True):
            np.testing.assert_array_equal(shared.basis, own.basis)
            np.testing.assert_array_equal(shared.weak_sigma, own.weak_sigma)
            assert (shared.names, shared.weak_names) == (own.names, own.weak_names)
        # A look that reads the subspace alone (the hold's looks again): the same subspace,
        # its names not made.
        unnamed = unseen_directions(model, x, data, noise, scale, nominal, start=start,
                                    named=False)
        np.testing.assert_array_equal(unnamed.basis, alone[1].basis)
        assert unnamed.names == () and len(alone[1].names) == alone[1].basis.shape[1] > 0
        extra.append(pair[1].basis.shape[1] - pair[0].basis.shape[1])
    assert extra[0] > 0 and extra[1] == 0


def test_unseen_names_pivot_on_what_the_subspace_moves() -> None:
    """A subspace near span{u0, u3 − u2} is named by the unknowns it moves: "u0" and "u2-u3".
    Pivots chosen by rank alone took u3 and u2, which it barely moves (1e-6), and their inverse
    made both directions read "u0"."""
    basis = np.linalg.qr(np.array([[1.0, 1.0], [0.0, 0.0], [0.0, 1e-6], [1e-6, 0.0]]))[0]
    names = _sparse_names(basis, np.ones(4), ("u0", "u1", "u2", "u3"))
    assert names == ("u0", "u2-u3")
