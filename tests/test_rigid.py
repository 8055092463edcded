"""Rigid transforms: angles to rotations and back, their derivatives, and the rigid fit."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from twin.geometry.rigid import (
    angles,
    is_rigid_transform,
    kabsch,
    rotation,
    rotation_derivatives,
    transform,
)


def test_rotation_is_z_y_x_of_fixed_axes() -> None:
    """R = Rz Ry Rx: scipy's extrinsic 'xyz' with the same angles, and back to the angles."""
    a = np.array([0.3, -0.4, 2.0])
    np.testing.assert_allclose(rotation(a), Rotation.from_euler("xyz", a).as_matrix(),
                               atol=1e-15)
    np.testing.assert_allclose(angles(rotation(a)), a, atol=1e-14)


def test_rotations_of_stacked_angles_are_scipys() -> None:
    """Angles (4, 5, 3), as a swarm's candidates carry a frame's: every rotation is scipy's
    extrinsic 'xyz' of its angles."""
    a = np.random.default_rng(1).uniform(-3.0, 3.0, (4, 5, 3))
    expected = Rotation.from_euler("xyz", a.reshape(-1, 3)).as_matrix().reshape(4, 5, 3, 3)
    np.testing.assert_allclose(rotation(a), expected, rtol=0, atol=1e-15)


def test_rotation_derivatives_match_differences() -> None:
    """∂R/∂a equals central differences of R."""
    a = np.array([0.2, 0.5, -1.1])
    eps = 1e-7
    numeric = np.stack([(rotation(a + e) - rotation(a - e)) / (2 * eps)
                        for e in np.eye(3) * eps])
    np.testing.assert_allclose(rotation_derivatives(a), numeric, atol=1e-8)


def test_kabsch_recovers_a_rigid_motion() -> None:
    """Points moved by a known rigid motion and a little noise: the fit finds the motion, and
    its RMS is the noise's."""
    rng = np.random.default_rng(0)
    source = rng.uniform(-0.5, 0.5, (50, 3))
    truth = transform([1.0, -2.0, 0.5], [0.3, -0.2, 2.9])
    target = source @ truth[:3, :3].T + truth[:3, 3] + rng.normal(scale=1e-5, size=(50, 3))
    fit = kabsch(source, target)
    np.testing.assert_allclose(fit.transform, truth, atol=1e-4)
    assert fit.rms_m == pytest.approx(np.sqrt(3) * 1e-5, rel=0.3)
    assert np.linalg.det(fit.transform[:3, :3]) > 0


def test_kabsch_never_reflects() -> None:
    """Mirrored points are fitted by a rotation, not a reflection."""
    source = np.random.default_rng(1).uniform(-1, 1, (10, 3))
    fit = kabsch(source, source * [1.0, 1.0, -1.0])
    assert np.linalg.det(fit.transform[:3, :3]) == pytest.approx(1.0)
    assert fit.rms_m > 0.1


def test_rigid_transform_test_agrees_with_numpy_allclose() -> None:
    """is_rigid_transform decides as numpy's allclose with its tolerances (R Rᵀ = I at atol
    1e-9, det R > 0, last row at allclose's defaults) over 7000 transforms: rotations, scaled
    or disturbed by 1e-12 to 1e-4, mirrored, with a last row off by 1e-10 to 1e-3, with a NaN."""
    rng = np.random.default_rng(3)

    def reference(matrix: np.ndarray) -> bool:
        turn = matrix[:3, :3]
        return bool(np.allclose(turn @ turn.T, np.eye(3), atol=1e-9)
                    and np.linalg.det(turn) > 0 and np.allclose(matrix[3], [0, 0, 0, 1]))

    decided = []
    for k in range(7000):
        matrix = np.eye(4)
        matrix[:3, :3] = Rotation.random(random_state=k).as_matrix()
        matrix[:3, 3] = rng.normal(size=3)
        case = k % 7
        if case == 1:
            matrix[:3, :3] *= 1 + rng.normal() * 10 ** rng.uniform(-12, -4)
        elif case == 2:
            matrix[:3, :3] += rng.normal(size=(3, 3)) * 10 ** rng.uniform(-12, -6)
        elif case == 3:
            matrix[:3, 0] *= -1
        elif case == 4:
            matrix[3, :3] = rng.normal(size=3) * 10 ** rng.uniform(-10, -6)
        elif case == 5:
            matrix[3, 3] = 1 + rng.normal() * 10 ** rng.uniform(-8, -3)
        elif case == 6:
            matrix[rng.integers(4), rng.integers(4)] = np.nan
        expected = reference(matrix)
        assert is_rigid_transform(matrix) == expected, (k, matrix)
        decided.append(expected)
    assert 0.3 < np.mean(decided) < 0.7  # both answers are tested
