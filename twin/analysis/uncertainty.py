"""Uncertainty of identified parameters and of the flange position they predict.

The Cramér–Rao bound for unbiased estimates from Gaussian length noise σ is the covariance
``C = σ² (JᵀJ)⁺`` of the unknowns. Every calibration holds what the training poses cannot see
at the nominal (:mod:`twin.analysis.unseen`: below the rank threshold, or less well determined
by the data than by the box), so the bound that fits it is the one of the **identifiable
combinations only**: ``C = σ² P (Pᵀ JᵀJ P)⁻¹ Pᵀ``, P the seen directions. (The plain
pseudo-inverse keeps directions a perturbed geometry lifts off zero by 1e-8 of the largest
singular value — d2 − d3 with few poses — and its bound is then their noise, not the
calibration's.)

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

from twin.analysis.identifiability import RANK_RTOL, measurement_identifiability
from twin.analysis.linearisation import chain_jacobian, linearise
from twin.analysis.unseen import Unseen, unseen_directions
from twin.arrays import Array
from twin.dataset import Measurements
from twin.model import Model


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


def seen_covariance(jacobian: ArrayLike, seen_x: ArrayLike, sigma_m: float) -> Array:
    """Covariance σ² P (Pᵀ JᵀJ P)⁻¹ Pᵀ of the unknowns of an estimator held along the unseen
    directions, shape (p, p), in m² / rad² units of x.

    Args:
        jacobian: Jacobian ∂r/∂x, shape (m, p), or any matrix with the same JᵀJ (its R factor,
            :class:`twin.analysis.linearisation.Linearisation`).
        seen_x: The seen directions P in the units of x, shape (p, q)
            (:attr:`twin.analysis.unseen.Unseen.seen_x`).
        sigma_m: Noise 1σ of a reading, m.
    """
    seen = np.asarray(seen_x, dtype=np.float64)
    reduced = parameter_covariance(np.asarray(jacobian, dtype=np.float64) @ seen, sigma_m)
    return np.asarray(seen @ reduced @ seen.T, dtype=np.float64)


def held_unseen(model: Model, x: ArrayLike, data: Measurements, sigma_m: float,
                row_weight: ArrayLike | None = None) -> Unseen:
    """What the poses of ``data`` cannot see at x with noise ``sigma_m`` (m; of a row scaled
    by ``row_weight`` when given), in the unknowns scaled by how far each may move
    (:meth:`twin.model.Model.scale`): what a calibration of such data holds whatever the values
    (the bound of every direction the data see, weak ones included: holding the weak ones a
    fit cannot tell from zero, :mod:`twin.analysis.unseen`, trades their variance for a bias
    the bound does not count)."""
    nominal = measurement_identifiability(model, np.zeros(model.n_params), data)
    return unseen_directions(model, x, data, sigma_m, model.scale(), nominal, row_weight)


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
    # J_i C J_iᵀ's trace as Σ (J C) ⊙ J: one matrix product over every pose's rows (an
    # unoptimised three-operand einsum took 4× longer)
    rows = jacobian.reshape(-1, jacobian.shape[-1])
    spread = (rows @ np.asarray(covariance, dtype=np.float64)).reshape(jacobian.shape)
    per_pose = np.sum(spread * jacobian, axis=(-2, -1))
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


def cramer_rao_covariance(model: Model, x_true: ArrayLike, data: Measurements, sigma_m: float,
                          row_sigma_m: ArrayLike | None = None) -> Array:
    """The Cramér–Rao covariance of the combinations the poses identify at that noise (the
    others every calibration holds), shape (p, p); arguments as :func:`cramer_rao_rms`."""
    weight = None if row_sigma_m is None else sigma_m / np.asarray(row_sigma_m, dtype=np.float64)
    triangle = linearise(model, x_true, data, weight).triangle
    return seen_covariance(triangle, held_unseen(model, x_true, data, sigma_m, weight).seen_x,
                           sigma_m)


def cramer_rao_rms(model: Model, x_true: ArrayLike, data: Measurements, sigma_m: float,
                   q_rad: ArrayLike, row_sigma_m: ArrayLike | None = None
                   ) -> tuple[float, float]:
    """Cramér–Rao bounds on the RMS position errors over the poses ``q_rad`` of the flange and
    of the measured point (eyelet, tracker target, ball), m each, of the combinations the
    poses identify at that noise (the others every calibration holds). With the attachment
    estimated the flange is not identified but the measured point is.

    Args:
        model: The measurement model that is fitted.
        x_true: The true unknowns, shape (p,).
        data: The poses that are measured (their readings are not used).
        sigma_m: Measurement noise 1σ, m.
        q_rad: Workspace poses where the errors are evaluated, shape (k, n).
        row_sigma_m: Each row's own noise 1σ, shape (M,), m, when the rows differ (the
            joints' noise through each row's Jacobian, :meth:`twin.problem.Problem.row_sigma`):
            the bound of the best estimator linear in the readings, which weights each row by
            1/σ_i² (Gauss–Markov; the Cramér–Rao bound itself for Gaussian noise).
    """
    covariance = cramer_rao_covariance(model, x_true, data, sigma_m, row_sigma_m)
    return _workspace_rms(model, x_true, model.poses(q_rad), covariance)


def _workspace_rms(model: Model, x: ArrayLike, poses: Measurements, covariance: Array
                   ) -> tuple[float, float]:
    """:func:`predicted_flange_rms` of the flange centre and of the measured point at the poses,
    m each, for a covariance (p, p) of x (p,); once where the point is the flange."""
    flange = predicted_flange_rms(chain_jacobian(model, x, poses, measured=False), covariance)
    if model.measures_flange:
        return flange, flange
    return flange, predicted_flange_rms(chain_jacobian(model, x, poses, measured=True),
                                        covariance)


def cramer_rao_flange_rms(
    model: Model, x_true: ArrayLike, data: Measurements, sigma_m: float, q_rad: ArrayLike,
    row_sigma_m: ArrayLike | None = None,
) -> float:
    """The flange's bound of :func:`cramer_rao_rms` alone, m."""
    covariance = cramer_rao_covariance(model, x_true, data, sigma_m, row_sigma_m)
    return predicted_flange_rms(model.flange_jacobian(x_true, model.poses(q_rad)), covariance)


HELD_ROW_TOL = 1e-9
"""An unknown whose unit vector has less than this in the seen directions is held entirely (its
σ is shown as not identified, not as zero)."""


class CalibrationUncertainty(NamedTuple):
    """How well a calibration determined its unknowns and the flange position."""

    noise_sigma_m: float
    """Length noise estimated from the training residuals, σ̂ = sqrt(‖r‖² / (m − rank)), m."""
    covariance: Array
    """Covariance of the unknowns as the calibration returns them, held at the start along
    the unseen directions (:func:`seen_covariance`), shape (p, p)."""
    sigma: Array
    """Standard deviation of each unknown, shape (p,), m and rad; NaN for an unknown held
    entirely (θ6 of a flange-centre cable)."""
    flange_rms_m: float
    """Predicted RMS flange-position error over the workspace poses, m, of the identifiable
    combinations (the others held at the nominal)."""
    point_rms_m: float = float("nan")
    """Predicted RMS position error of the measured point (eyelet, tracker target, ball) over
    the workspace poses, m: what an estimated attachment identifies."""


def calibration_uncertainty(
    model: Model,
    x: ArrayLike,
    train: Measurements,
    rank: int,
    q_workspace_rad: ArrayLike,
    unseen: Unseen,
    row_weight: ArrayLike | None = None,
) -> CalibrationUncertainty:
    """Covariance and predicted accuracy of an identified x from its training data — with
    priors (:meth:`twin.model.Model.prior_weight`), the posterior's: the data's information
    ``JᵀJ / σ̂²`` and the priors' ``diag(1/σ_p²)`` added.

    Args:
        model: The fitted measurement model.
        x: Identified unknowns, shape (p,).
        train: The poses and lengths it was fitted to.
        rank: The combinations the training poses identify (the noise estimate's degrees of
            freedom are the residuals less these).
        q_workspace_rad: Poses where the flange accuracy is predicted, shape (k, n), rad.
        unseen: What the training poses cannot see (held at the start): the covariance and the
            accuracy are those of the other combinations.
        row_weight: σ / σ_i of each training row (M,) when the rows' noise differs (errors
            in variables): the rows are scaled by it, and σ̂ is that of a scaled row.
    """
    x = np.asarray(x, dtype=np.float64)
    linearised = linearise(model, x, train, row_weight)
    noise = residual_sigma(linearised.residuals, rank)
    prior = model.prior_weight()
    # J's R factor in place of J: the same JᵀJ, a p-row matrix to factorise.
    triangle = linearised.triangle
    seen = unseen.seen  # one factorisation for P = S Q and the rows of Q
    seen_x = unseen.scale[:, None] * seen
    covariance = seen_covariance(
        np.concatenate([triangle / noise, np.diag(prior)[prior > 0]]), seen_x, 1.0) \
        if noise > 0 else seen_covariance(triangle, seen_x, 0.0)
    held = np.linalg.norm(seen, axis=1) < HELD_ROW_TOL
    sigma = np.sqrt(np.maximum(np.diag(covariance), 0.0))
    flange_rms, point_rms = _workspace_rms(model, x, model.poses(q_workspace_rad), covariance)
    return CalibrationUncertainty(noise_sigma_m=noise, covariance=covariance,
                                  sigma=np.where(held, np.nan, sigma), flange_rms_m=flange_rms,
                                  point_rms_m=point_rms)
