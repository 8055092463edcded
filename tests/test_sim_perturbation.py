"""Random D-H errors: distributions, scales and the paper's bounds."""

from __future__ import annotations

import numpy as np
import pytest

from twin.scenario import Perturbation
from twin.unknowns.dh import BOUND_M as DH_BOUND_M
from twin.unknowns.dh import BOUND_RAD as DH_BOUND_RAD


def test_uniform_draws_stay_within_their_scale() -> None:
    """Uniform draws fill ±scale per parameter and are reproducible from the generator."""
    scale = np.repeat([[1e-3], [2e-3], [1e-3], [3e-3]], 6, axis=1)
    draws = np.array([Perturbation("uniform", scale).draw(np.random.default_rng(s))
                      for s in range(400)])
    assert np.all(np.abs(draws) <= scale)
    assert np.max(np.abs(draws), axis=0) == pytest.approx(scale, rel=0.05)
    again = Perturbation("uniform", scale).draw(np.random.default_rng(0))
    assert np.array_equal(draws[0], again)


def test_normal_draws_have_sigma_scale_and_are_clipped_to_the_bounds() -> None:
    """Normal draws have σ = scale, but never leave the paper's ±5 mm / ±8° box."""
    scale = np.repeat([[1e-3], [4e-3], [0.01], [0.1]], 6, axis=1)
    draws = np.array([Perturbation("normal", scale).draw(np.random.default_rng(s))
                      for s in range(2000)])
    assert np.std(draws[:, 0], axis=0) == pytest.approx(scale[0], rel=0.1)
    assert np.max(np.abs(draws[:, :2])) <= DH_BOUND_M
    assert np.max(np.abs(draws[:, 2:])) <= DH_BOUND_RAD
    assert np.isclose(np.max(np.abs(draws[:, 1])), DH_BOUND_M)


def test_bad_perturbations_are_rejected() -> None:
    """Unknown distributions and negative scales are errors."""
    with pytest.raises(ValueError):
        Perturbation("triangular", np.zeros((4, 6)))
    with pytest.raises(ValueError):
        Perturbation("uniform", -np.ones((4, 6)))
