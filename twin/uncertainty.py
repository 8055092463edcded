"""Uncertainty of identified parameters and of the flange position they predict.

The Cramér–Rao bound for unbiased estimates from Gaussian length noise σ is the covariance
``C = σ² (JᵀJ)⁺`` of the unknowns; the pseudo-inverse leaves out the directions the cable cannot
see, which do not move the flange either (the two Jacobians share their null space for the
IRB 120), so the bound on the flange position stays finite and meaningful.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.cable import CableModel, Measurements
from twin.kinematics import flange_position, flange_position_jacobian

Array = NDArray[np.float64]

RANK_RTOL = 1e-8
"""Singular values below this fraction of the largest are treated as zero."""


def parameter_covariance(jacobian: ArrayLike, sigma_m: float, rtol: float = RANK_RTOL) -> Array:
    """Covariance σ² (JᵀJ)⁺ of the unknowns, shape (p, p), in m² / rad² units of x.

    Args:
        jacobian: Cable-length Jacobian ∂r/∂x, shape (m, p).
        sigma_m: Length noise 1σ, m.
        rtol: Relative singular-value cutoff of the pseudo-inverse.
    """
    _, s, vt = np.linalg.svd(np.asarray(jacobian, dtype=np.float64), full_matrices=False)
    keep = s > rtol * s[0]
    v = vt[keep].T / s[keep]
    return np.asarray(sigma_m**2 * (v @ v.T), dtype=np.float64)


def flange_error_rms(dh_a: ArrayLike, dh_b: ArrayLike, q_rad: ArrayLike) -> float:
    """RMS over poses of the distance between the flange centres of two tables, m."""
    difference = flange_position(dh_a, q_rad) - flange_position(dh_b, q_rad)
    return float(np.sqrt(np.mean(np.sum(difference**2, axis=-1))))


def predicted_flange_rms(dh: ArrayLike, covariance_dh: ArrayLike, q_rad: ArrayLike) -> float:
    """RMS flange-position error over poses implied by a D-H covariance, m.

    Args:
        dh: D-H table at which to linearise, shape (4, n).
        covariance_dh: Covariance of the D-H errors, shape (4n, 4n).
        q_rad: Poses, shape (m, n).

    Returns:
        sqrt(mean_i trace(J_i C J_iᵀ)) with J_i the flange-position Jacobian at pose i.
    """
    _, jacobian = flange_position_jacobian(dh, q_rad)
    per_pose = np.einsum("mij,jk,mik->m", jacobian, np.asarray(covariance_dh), jacobian)
    return float(np.sqrt(np.mean(per_pose)))


def cramer_rao_flange_rms(
    model: CableModel, x_true: ArrayLike, data: Measurements, sigma_m: float, q_rad: ArrayLike
) -> float:
    """Cramér–Rao bound on the RMS flange-position error over the poses ``q_rad``, m.

    Args:
        model: The cable model that is fitted.
        x_true: The true unknowns, shape (p,).
        data: The poses that are measured (their lengths are not used).
        sigma_m: Length noise 1σ, m.
        q_rad: Workspace poses where the flange error is evaluated, shape (k, n).
    """
    _, jacobian = model.jacobian(x_true, data)
    covariance = parameter_covariance(jacobian, sigma_m)[: model.n_dh, : model.n_dh]
    dh = model.split(np.asarray(x_true, dtype=np.float64))[0]
    return predicted_flange_rms(dh, covariance, q_rad)
