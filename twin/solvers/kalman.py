"""Kalman-filter passes over the training poses, shared by M1 (EKF), M4 (UKF), M5 and M6 (EKF).

The unknowns are the filter state with a random-walk model ``x_{i+1} = x_i + w``, ``w ~ N(0, Q)``
with a small Q (1σ = 1e-6 of the search bound per update: 5 nm, 0.14 µrad), and a prior
covariance from the bounds' scale (1σ = half the bound: 2.5 mm, 4°). Each training pose is one
scalar measurement ``z_i = L_i = ℓ(x, q_i) + v``, ``v ~ N(0, R)``. One iteration is one pass
over the training poses in a fixed order, shuffled once from the method's generator.

R per pass is ``max(σ², f(x_s))``, σ = ``problem.sigma_m`` and f(x_s) the mean squared residual at
the pass's start (with a robust loss, the mean row cost): the filter counts the misfit it sees as
measurement noise.

With a robust loss (:mod:`twin.loss`) the measurement model is, per row i, ``v_i ~ N(0, R /
ρ'(z_i))`` with z_i = (r_i(x_s) / c)² at the pass's linearisation point: a row far out counts as
noisier, by the IRLS weight of the loss — the Gaussian whose information matches the loss's
weight at the current residual (an M-estimation Kalman filter). Inliers keep R; a Huber row ten
scales out has ten times its variance, a Cauchy row a hundred and one times. With R = σ² alone
(method-notes §4) the filter is overconfident whenever the model cannot fit to σ — before it has
converged, and for good when there are non-geometric errors: on scenarios/paper_irb120.toml
(σ = 0.01 mm, misfit 0.3 mm) the EKF ended at 5.3 mm validation RMSE, worse than the nominal
model's 2.2 mm. On geometric data f(x_s) falls to σ² after a pass or two, and R = σ² again.

Iterated passes (our reading; see docs/methods.md): every pass filters all training poses from
the prior (x0, P0), with the measurement model linearised at the previous pass's posterior
(x_s, P_s) — the iterated EKF, and for the UKF the iterated posterior linearisation filter
(García-Fernández et al. 2015). The first pass is not a plain EKF: a plain EKF re-linearises each
measurement at the running estimate, while every pass here, the first included, linearises all
poses once at the pass's start point (x0 for the first pass) — a linearised Kalman filter whose
passes re-linearise. Continuing instead from the
previous pass's posterior uses every pose again as new information: the covariance then shrinks
pass after pass while the directions the cable barely sees keep the prior's, and the estimate
drifts along them (on one paper-scenario trial it ran into a ±8° bound after 16 passes and the
validation RMSE rose from 0.27 to 2.4 mm). The estimate is projected onto the bounds after each
pass.

Stopping (:mod:`twin.stopping`): under ``converge``, when a pass moves the estimate by less than
``xtol`` of the unknowns' scale (*xtol*: the iteration has reached its fixed point) or changes f
by less than ``ftol`` (relative, *ftol*); under the paper's protocol, standalone M1 stops when f
changes by less than 0.001 mm² (*f_change*) and a cascade's filter stage runs all its passes.

Linearisation, once per pass and batched over the poses (our choice, for speed): at the start
of a pass the measurement model of every pose is linearised around x_s in ONE batched
evaluation, ``ℓ_i(x) ≈ ℓ̂_i + H_i (x − x_s)``:

- EKF (:func:`ekf_linearisation`): ℓ̂ = ℓ(x_s), H = the analytic Jacobian;
- UKF (:func:`ukf_linearisation`): 2p sigma points ``x_s ± sqrt(p)·chol(P)`` (and x_s, for f)
  evaluated on all poses in one call with 2p + 1 tables; ℓ̂ = the sigma-point mean, H = the
  statistical (regression) linearisation ``P_xzᵀ P⁻¹``, and the variance it leaves unexplained is
  added to that pose's R — the unscented transform in its statistically-linearised form.

Then the per-pose updates run sequentially through the pass, each conditioning on the previous
ones; each is a handful of O(p²) numpy operations and evaluates nothing.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from twin.arrays import Array
from twin.solvers.base import Outcome, Tracker
from twin.stopping import Budget, StopReason, small_step

PRIOR_FRACTION = 0.5
"""Prior 1σ of each unknown as a fraction of its search bound."""
PROCESS_FRACTION = 1e-6
"""Random-walk 1σ per update as a fraction of the search bound."""


class Linearisation(NamedTuple):
    """Linear model of the training residuals around x_s: ``r(x) ≈ residual + H (x − x_s)``."""

    x: Array
    """Linearisation point x_s, shape (p,)."""
    residual_m: Array
    """Predicted residuals at x_s, shape (m,), m."""
    jacobian: Array
    """H, shape (m, p)."""
    extra_variance_m2: Array
    """Variance of each residual the linear model does not explain, added to R; shape (m,), m²."""
    f_m2: float
    """Objective f at x_s, m²."""
    weights: Array
    """The loss's weight ρ'(z) of each residual at x_s, shape (m,): R of row i is R / weight."""


Linearise = Callable[[Tracker, Array, Array], Linearisation]
"""``linearise(tracker, x (p,), P (p, p)) -> Linearisation``."""


def ekf_linearisation(tracker: Tracker, x: Array, P: Array) -> Linearisation:
    """First-order (EKF) linearisation at x: residuals and analytic Jacobian, one evaluation."""
    r, J = tracker.model_jacobian(x)
    problem = tracker.problem
    return Linearisation(x, r, J, np.zeros_like(r), float(problem.cost(r)),
                         problem.loss_weights(r))


def ukf_linearisation(tracker: Tracker, x: Array, P: Array) -> Linearisation:
    """Unscented linearisation at x with covariance P, from 2p + 1 tables in one evaluation.

    The symmetric sigma set without a weighted centre (scaled unscented transform with λ = 0,
    weights 1/(2p)) keeps every weight positive, so no variance can come out negative; x itself
    is evaluated alongside, only for f.
    """
    p = x.size
    offsets = np.sqrt(p) * np.linalg.cholesky(P).T  # row j: the j-th sigma offset
    sigma = np.concatenate([x[None], x + offsets, x - offsets])
    r = tracker.residuals(sigma)  # (2p + 1, m)
    spread = r[1:] - np.mean(r[1:], axis=0)
    offsets_all = np.concatenate([offsets, -offsets])
    cross = offsets_all.T @ spread / (2 * p)  # P_xz, (p, m)
    H = np.linalg.solve(P, cross).T
    explained = np.einsum("mp,pm->m", H, cross)
    total = np.mean(spread**2, axis=0)
    problem = tracker.problem
    return Linearisation(x, np.mean(r[1:], axis=0), H, np.maximum(total - explained, 0.0),
                         float(problem.cost(r[0])), problem.loss_weights(r[0]))


def run_filter(
    tracker: Tracker,
    x0: Array,
    budget: Budget,
    rng: np.random.Generator,
    linearise: Linearise,
) -> Outcome:
    """Run filter passes over the training poses from ``x0`` (p,) until ``budget`` stops them.

    Args:
        tracker: Evaluates the problem and records f after each pass.
        x0: Start (prior mean), shape (p,).
        budget: Pass limit (one iteration = one pass) and stopping tests.
        rng: Draws the pose order (once).
        linearise: :func:`ekf_linearisation` or :func:`ukf_linearisation`.
    """
    problem = tracker.problem
    lower, upper, unit = problem.lower, problem.upper, problem.scale
    x_prior = np.clip(x0, lower, upper)
    half = 0.5 * (upper - lower)  # the bound of a symmetric box
    P_prior = np.diag((PRIOR_FRACTION * half) ** 2)
    q_m2 = (PROCESS_FRACTION * half) ** 2
    diagonal = np.diag_indices_from(P_prior)
    x, P = x_prior, P_prior
    model = linearise(tracker, x, P)
    # Every residual row is a scalar measurement: a pose of a 3-D kind gives three.
    order = rng.permutation(model.residual_m.size)
    # A prior row (the last ones) is a reading of variance σ² exactly: no misfit to count.
    prior = order >= model.residual_m.size - problem.prior_rows
    if not tracker.started:
        tracker.record(x, model.f_m2)
    for _ in range(budget.max_iterations):
        r_m2 = max(problem.sigma_m**2, model.f_m2)  # see the module docstring
        x, P = x_prior.copy(), P_prior.copy()  # each pass filters from the prior: see above
        for i, exact in zip(order, prior, strict=True):  # sequential by nature: each update
            P[diagonal] += q_m2                           # conditions on the ones before it
            h = model.jacobian[i]
            predicted_m = model.residual_m[i] + h @ (x - model.x)
            pxz = P @ h
            s = float(h @ pxz) + (problem.sigma_m**2 if exact else r_m2) / model.weights[i] \
                + model.extra_variance_m2[i]
            gain = pxz / s
            x -= gain * predicted_m
            P -= np.outer(gain, pxz)
        x = np.clip(x, lower, upper)
        previous = model
        model = linearise(tracker, x, P)
        tracker.record(x, model.f_m2)
        change = abs(previous.f_m2 - model.f_m2)
        if budget.xtol > 0 and small_step(x - previous.x, x, unit, budget.xtol):
            return Outcome(x, StopReason.XTOL)
        if budget.ftol > 0 and change <= budget.ftol * previous.f_m2:
            return Outcome(x, StopReason.FTOL)
        if budget.ftol_m2 > 0 and change < budget.ftol_m2:
            return Outcome(x, StopReason.F_CHANGE)
    return Outcome(x, StopReason.MAX_ITERATIONS)


def ekf(tracker: Tracker, x0: Array, budget: Budget, rng: np.random.Generator) -> Outcome:
    """EKF passes (M1, and the first stage of M5 and M6); see :func:`run_filter`."""
    return run_filter(tracker, x0, budget, rng, ekf_linearisation)


def ukf(tracker: Tracker, x0: Array, budget: Budget, rng: np.random.Generator) -> Outcome:
    """UKF passes (first stage of M4); see :func:`run_filter`."""
    return run_filter(tracker, x0, budget, rng, ukf_linearisation)
