"""Uncertainty of identified parameters and of the flange position they predict.

The Cramér–Rao bound for unbiased estimates from Gaussian length noise σ is the covariance
``C = σ² (JᵀJ)⁺`` of the unknowns; the pseudo-inverse leaves out the directions the cable cannot
see, which do not move the flange either (the two Jacobians share their null space for the
IRB 120), so the bound on the flange position stays finite and meaningful.

After a calibration the noise is not known: it is estimated from the training residuals as
σ̂² = ‖r‖² / (m − rank). Per-parameter standard deviations are those of the base parameters
(:mod:`twin.analysis.identifiability`) with the dependent ones held at their start values — the only
reading in which a single parameter has a finite variance; the dependent ones have none.
With the port estimated, the base frame is only defined relative to the port up to a shift
along and a turn about the first joint axis; flange accuracies then leave that motion out.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from twin.analysis.identifiability import RANK_RTOL
from twin.arrays import Array
from twin.dataset import Measurements
from twin.model import Model
from twin.robot import RobotModel

WORKSPACE_POSES = 1000
"""Random poses within the joint limits over which the flange accuracy is predicted."""

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


def rms_distance(a_m: ArrayLike, b_m: ArrayLike) -> float:
    """RMS over poses of the distance between two sets of points, shapes (k, 3), m."""
    difference = np.asarray(a_m, dtype=np.float64) - np.asarray(b_m, dtype=np.float64)
    return float(np.sqrt(np.mean(np.sum(difference**2, axis=-1))))


def flange_sigma(flange_jacobian: ArrayLike, covariance: ArrayLike) -> Array:
    """Predicted RMS flange-position error at each pose implied by a covariance of x.

    Args:
        flange_jacobian: ∂(flange)/∂x at each pose, shape (k, 3, p)
            (:meth:`twin.model.Model.flange_jacobian`).
        covariance: Covariance of x, shape (p, p).

    Returns:
        sqrt(trace(J_i C J_iᵀ)) per pose, shape (k,), m: the 3-D position error's RMS.
    """
    jacobian = np.asarray(flange_jacobian, dtype=np.float64)
    per_pose = np.einsum("mij,jk,mik->m", jacobian, np.asarray(covariance), jacobian)
    return np.asarray(np.sqrt(np.maximum(per_pose, 0.0)), dtype=np.float64)


def predicted_flange_rms(flange_jacobian: ArrayLike, covariance: ArrayLike) -> float:
    """RMS flange-position error over poses implied by a covariance of x, m:
    sqrt(mean_i trace(J_i C J_iᵀ)), arguments as :func:`flange_sigma`."""
    return float(np.sqrt(np.mean(flange_sigma(flange_jacobian, covariance) ** 2)))


def residual_sigma(residuals_m: ArrayLike, rank: int) -> float:
    """Noise estimate σ̂ = sqrt(‖r‖² / (m − rank)) from fitted residuals, m.

    Args:
        residuals_m: Residuals at the estimate, shape (m,), m.
        rank: Number of identified combinations.

    Raises:
        ValueError: if there are no more residuals than the rank.
    """
    r = np.asarray(residuals_m, dtype=np.float64)
    if r.size <= rank:
        raise ValueError(f"{r.size} residuals for rank {rank}: no degree of freedom left")
    return float(np.sqrt(r @ r / (r.size - rank)))


def base_covariance(jacobian: ArrayLike, base: ArrayLike, sigma_m: float) -> Array:
    """Covariance σ² (J_Bᵀ J_B)⁻¹ of the base parameters, embedded in shape (p, p).

    Rows and columns of the dependent unknowns (held fixed) are zero. Its flange-position
    covariance equals that of :func:`parameter_covariance`: both are generalised inverses of
    JᵀJ, and flange motions lie in J's row space.

    Args:
        jacobian: Cable-length Jacobian ∂r/∂x, shape (m, p).
        base: Indices of the base parameters, shape (L,), with J[:, base] of full rank.
        sigma_m: Length noise 1σ, m.
    """
    J = np.asarray(jacobian, dtype=np.float64)
    index = np.asarray(base, dtype=np.intp)
    covariance = np.zeros((J.shape[1], J.shape[1]))
    covariance[np.ix_(index, index)] = parameter_covariance(J[:, index], sigma_m)
    return covariance


def parameter_sigma(covariance: ArrayLike, base: ArrayLike) -> Array:
    """Per-unknown standard deviation, shape (p,), NaN for those outside ``base``."""
    variance = np.diag(np.asarray(covariance, dtype=np.float64))
    sigma = np.full(variance.shape, np.nan)
    index = np.asarray(base, dtype=np.intp)
    sigma[index] = np.sqrt(variance[index])
    return sigma


def workspace_grid(robot: RobotModel, n_per_axis: int) -> tuple[Array, Array, Array]:
    """A grid over joints 2 and 3 within their limits, the other joints at 0.

    These two joints set the reach and height of the wrist; the map over them shows where
    in the workspace a calibration is accurate.

    Returns:
        ``(q2_rad, q3_rad, q_rad)``: axes (n_per_axis,) each, and poses
        (n_per_axis², n) with q2 varying slowest.
    """
    q2 = np.linspace(robot.lower_rad[1], robot.upper_rad[1], n_per_axis)
    q3 = np.linspace(robot.lower_rad[2], robot.upper_rad[2], n_per_axis)
    q = np.zeros((n_per_axis * n_per_axis, robot.n_joints))
    q[:, 1], q[:, 2] = (axis.ravel() for axis in np.meshgrid(q2, q3, indexing="ij"))
    return q2, q3, q


def cramer_rao_flange_rms(
    model: Model, x_true: ArrayLike, data: Measurements, sigma_m: float, q_rad: ArrayLike
) -> float:
    """Cramér–Rao bound on the RMS flange-position error over the poses ``q_rad``, m.

    Args:
        model: The measurement model that is fitted.
        x_true: The true unknowns, shape (p,).
        data: The poses that are measured (their readings are not used).
        sigma_m: Measurement noise 1σ, m.
        q_rad: Workspace poses where the flange error is evaluated, shape (k, n).
    """
    _, jacobian = model.identifiable_jacobian(x_true, data)
    covariance = parameter_covariance(jacobian, sigma_m)
    return predicted_flange_rms(model.flange_jacobian(x_true, model.poses(q_rad)), covariance)


def cramer_rao_point_rms(
    model: Model, x_true: ArrayLike, data: Measurements, sigma_m: float, q_rad: ArrayLike
) -> float:
    """Cramér–Rao bound on the RMS position error of the measured point (eyelet, tracker
    target, ball) over the poses ``q_rad``, m; arguments as :func:`cramer_rao_flange_rms`.
    With the attachment estimated the flange is not identified but this point is."""
    _, jacobian = model.identifiable_jacobian(x_true, data)
    covariance = parameter_covariance(jacobian, sigma_m)
    return predicted_flange_rms(model.position_jacobian(x_true, model.poses(q_rad)), covariance)


class CalibrationUncertainty(NamedTuple):
    """How well a calibration determined its unknowns and the flange position."""

    noise_sigma_m: float
    """Length noise estimated from the training residuals, σ̂ = sqrt(‖r‖² / (m − rank)), m."""
    covariance: Array
    """Covariance of the base parameters, embedded in shape (p, p) (zero for dependent ones)."""
    sigma: Array
    """Standard deviation of each unknown, shape (p,), m and rad; NaN if not identifiable."""
    flange_rms_m: float
    """Predicted RMS flange-position error over the workspace poses, m."""
    point_rms_m: float = float("nan")
    """Predicted RMS position error of the measured point (eyelet, tracker target, ball) over
    the workspace poses, m: what an estimated attachment identifies."""


def calibration_uncertainty(
    model: Model,
    x: ArrayLike,
    train: Measurements,
    base: ArrayLike,
    q_workspace_rad: ArrayLike,
) -> CalibrationUncertainty:
    """Covariance and predicted accuracy of an identified x from its training data.

    Args:
        model: The fitted measurement model.
        x: Identified unknowns, shape (p,).
        train: The poses and lengths it was fitted to.
        base: Indices of the base parameters, shape (L,).
        q_workspace_rad: Poses where the flange accuracy is predicted, shape (k, n), rad.
    """
    x = np.asarray(x, dtype=np.float64)
    residuals, jacobian = model.identifiable_jacobian(x, train)
    base = np.asarray(base, dtype=np.intp)
    noise = residual_sigma(residuals, base.size)
    covariance = base_covariance(jacobian, base, noise)
    poses = model.poses(q_workspace_rad)
    return CalibrationUncertainty(
        noise_sigma_m=noise,
        covariance=covariance,
        sigma=parameter_sigma(covariance, base),
        flange_rms_m=predicted_flange_rms(model.flange_jacobian(x, poses), covariance),
        point_rms_m=predicted_flange_rms(model.position_jacobian(x, poses), covariance),
    )
