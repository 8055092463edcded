"""The gauge-free error's fit (:func:`twin.analysis.gauge.gauge_free_rms`): the motions' analytic
Jacobian against central differences, and the fit against scipy's least_squares on finite
differences of the same distances."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from twin.analysis.gauge import (
    FLANGE_SHIFT,
    MOTIONS,
    PIN_TURN,
    Gauge,
    Motion,
    _moved,
    _moved_jacobian,
    gauge_free_rms,
)
from twin.geometry.rigid import exp_rotation

STEP = 1e-6
"""Central-difference step of the motions' parameters (rad, m, scale)."""
SLANTED = Motion("shift of the flange along (0.60, 0.00, 0.80) in its own frame",
                 FLANGE_SHIFT, -1, PIN_TURN, (0.6, 0.0, 0.8))
EVERY_KIND = (*MOTIONS, SLANTED)
"""Every candidate: turns about frame 0's axes and about the port, shifts, the scale, shifts of
the flange along its axes and along a slanted direction."""


def _gauge(rng: np.random.Generator, motions: tuple[Motion, ...], unnamed: int,
           port: bool) -> Gauge:
    """A gauge over 40 random points, a tilted and shifted frame 0, random flange turns and
    ``unnamed`` orthonormal fields."""
    points = rng.uniform(-0.8, 0.8, (40, 3))
    fields = np.linalg.qr(rng.normal(0.0, 1.0, (points.size, max(unnamed, 1))))[0][:, :unnamed]
    return Gauge(motions, fields, points, exp_rotation(rng.normal(0.0, 1.0, (40, 3))),
                 rng.normal(0.0, 0.1, 3), exp_rotation(rng.normal(0.0, 0.3, 3)),
                 np.array([0.0, 0.0, 0.1]), rng.normal(0.0, 0.5, 3) if port else None)


def _rms(points: np.ndarray, truth: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum((points - truth) ** 2, axis=1))))


@pytest.mark.parametrize("seed", range(3))
def test_moved_jacobian_matches_central_differences(seed: int) -> None:
    """∂(moved points)/∂(parameters) of every kind of motion, at parameters far from zero (a
    turn of a few degrees, where the right Jacobian of Exp is not the identity), equals central
    differences of the motions applied exactly; the points come with it as they are."""
    rng = np.random.default_rng(seed)
    gauge = _gauge(rng, EVERY_KIND, 2, port=True)
    parameters = rng.normal(0.0, 0.05, len(EVERY_KIND) + 2)
    points, analytic = _moved_jacobian(gauge, parameters)
    numeric = np.stack([(_moved(gauge, parameters + STEP * e)
                         - _moved(gauge, parameters - STEP * e)).ravel() / (2 * STEP)
                        for e in np.eye(parameters.size)], axis=1)
    assert np.array_equal(points, _moved(gauge, parameters))
    assert analytic.shape == numeric.shape
    np.testing.assert_allclose(analytic, numeric, rtol=0.0, atol=1e-8)


@pytest.mark.parametrize("port", [True, False], ids=["port", "no port"])
def test_gauge_free_rms_finds_the_minimum_a_finite_difference_fit_finds(port: bool) -> None:
    """Points moved by a known turn about frame 0's axis, a shift, a scale, a flange shift, a
    turn about the port and an unnamed motion, plus noise, against scipy's least_squares on
    finite differences of the same distances (the referee): the same RMS to 1e-12 m, below
    the raw one; with the noise left out, zero."""
    rng = np.random.default_rng(7)
    motions = (MOTIONS[0], MOTIONS[1], MOTIONS[6], MOTIONS[7], *(MOTIONS[10:11] if port else ()))
    gauge = _gauge(rng, motions, 1, port=port)
    true_parameters = rng.normal(0.0, 1e-3, len(motions) + 1)
    truth = _moved(gauge, true_parameters)
    assert gauge_free_rms(gauge, truth) < 1e-12
    noisy = truth + rng.normal(0.0, 1e-4, truth.shape)
    referee = least_squares(lambda p: (_moved(gauge, p) - noisy).ravel(),
                            np.zeros(true_parameters.size), method="lm", xtol=1e-15,
                            ftol=1e-15)
    found = gauge_free_rms(gauge, noisy)
    assert abs(found - _rms(_moved(gauge, referee.x), noisy)) < 1e-12
    assert found < _rms(gauge.points_m, noisy)


def test_gauge_free_rms_without_motions_is_the_raw_rms() -> None:
    """No unobservable motion: the plain RMS distance."""
    rng = np.random.default_rng(3)
    gauge = _gauge(rng, (), 0, port=False)
    truth = gauge.points_m + rng.normal(0.0, 1e-4, gauge.points_m.shape)
    assert gauge_free_rms(gauge, truth) == _rms(gauge.points_m, truth)
