"""Steps in a sequence of residuals: rows where the level jumps by more than the noise allows.

A drawstring re-hooked, an encoder re-zeroed, a new session: the readings of the rows after it
are all off by the same amount. A fixed-port model cannot explain such a step; the fit shares
it out over the geometry (the residuals left are a blurred step, not a clean one) and the
misfit test blames the robot model. The test here asks, for each place k between rows in the
recorded order, whether a step there — the regressor s_k = [0 … 0 1 … 1] of the rows from k on
— explains what the fit left, *beside* what the model's unknowns could take up (the columns of
its Jacobian J) and a slow drift (a constant and a line in the row order):

    with Q an orthonormal basis of [J, 1, t] and r̃ = r − Q Qᵀ r,
    size_k = s̃_kᵀ r̃ / ‖s̃_k‖²,  s̃_k = s_k − Q Qᵀ s_k   (the step fitted jointly: Frisch–Waugh)
    z_k = size_k ‖s̃_k‖ / σ_k,   σ_k² = (‖r̃‖² − size_k² ‖s̃_k‖²) / (dof − 1),

σ_k the residuals' own scatter once the step is taken out, or the stated noise if larger (a
model that misses something scatters more than the encoder). A step is named at the place of
largest |z_k| when it exceeds the normal quantile of level :data:`ALPHA` shared over every
place (Bonferroni: a capture without steps reports one with probability below ALPHA); it then
joins [J, 1, t] and the next is sought; the sizes of all are fitted together at the end. A
lone outlier does not pass (its own scatter is the
yardstick), nor does a drift (the line takes it). Every sum over k is a cumulative sum: O(m p).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from twin.arrays import Array

ALPHA = 1e-3
"""Level of the step test over all places of one sequence together (the false-alarm rate)."""
MAX_STEPS = 20
"""Most steps named in one sequence."""
RANK_RTOL = 1e-9
"""Singular values of the nuisance columns (each scaled to unit norm) below this fraction of
the largest add no direction."""


class Step(NamedTuple):
    """A jump of the residuals' level."""

    row: int
    """The first row after the jump (0-based, in the order given)."""
    size_m: float
    """How far the level moves there (after − before), m."""
    z: float
    """The jump in units of its noise."""


def _basis(columns: Array) -> Array:
    """An orthonormal basis of the columns' span, shape (m, rank)."""
    norms = np.linalg.norm(columns, axis=0)
    scaled = columns[:, norms > 0] / norms[norms > 0]
    if not scaled.shape[1]:
        return scaled
    u, singular, _ = np.linalg.svd(scaled, full_matrices=False)
    return np.asarray(u[:, singular > RANK_RTOL * singular[0]], dtype=np.float64)


def _tail_sums(values: Array) -> Array:
    """Σ_{i ≥ k} values[i] for k = 1 … m−1, shape (m−1, ...)."""
    return np.asarray(np.cumsum(values[::-1], axis=0)[::-1][1:], dtype=np.float64)


def _best(r: Array, basis: Array, sigma_m: float) -> tuple[int, float, float]:
    """The place k (1 … m−1) of the largest |z_k|, its step size and z (module docstring)."""
    m = r.size
    free = r - basis @ (basis.T @ r)
    dof = m - basis.shape[1] - 1
    along = _tail_sums(free)                       # s̃_kᵀ r̃ = s_kᵀ r̃
    norm2 = np.arange(m - 1, 0, -1) - np.sum(_tail_sums(basis) ** 2, axis=1)
    usable = norm2 > RANK_RTOL * m
    size = np.where(usable, along / np.where(usable, norm2, 1.0), 0.0)
    left = np.maximum(float(free @ free) - size**2 * norm2, 0.0) / max(dof - 1, 1)
    z = size * np.sqrt(np.maximum(norm2, 0.0)) / np.maximum(np.sqrt(left), sigma_m)
    k = int(np.argmax(np.abs(z)))
    return k + 1, float(size[k]), float(z[k])


def find_steps(residuals_m: ArrayLike, stated_sigma_m: float, jacobian: ArrayLike | None = None
               ) -> tuple[Step, ...]:
    """The steps of a sequence of residuals, in row order (module docstring).

    Args:
        residuals_m: One residual per row, in the order the rows were recorded, shape (m,), m.
        stated_sigma_m: The noise of a reading the fit was told, m.
        jacobian: ∂r/∂x of the model the residuals are a fit of, shape (m, p): what its
            unknowns could take up of a step; None for a bare sequence.
    """
    r = np.asarray(residuals_m, dtype=np.float64)
    m = r.size
    t = np.linspace(-1.0, 1.0, m)
    columns = [np.ones((m, 1)), t[:, None]]
    if jacobian is not None:
        columns.insert(0, np.asarray(jacobian, dtype=np.float64).reshape(m, -1))
    nuisance = np.hstack(columns)
    from scipy.special import ndtri

    threshold = float(ndtri(1.0 - ALPHA / (2.0 * max(m - 1, 1))))
    found: list[Step] = []
    while len(found) < MAX_STEPS and m - nuisance.shape[1] > 3:
        basis = _basis(nuisance)
        if m - basis.shape[1] <= 3:
            break
        row, size, z = _best(r, basis, stated_sigma_m)
        if abs(z) <= threshold:
            break
        found.append(Step(row, size, z))
        nuisance = np.column_stack([nuisance, (np.arange(m) >= row).astype(np.float64)])
    if not found:
        return ()
    # Each size fitted beside the others (found one by one, the first took up some of the next).
    sizes = np.linalg.lstsq(nuisance, r, rcond=None)[0][-len(found):]
    return tuple(sorted(step._replace(size_m=float(size))
                        for step, size in zip(found, sizes, strict=True)))


__all__ = ["ALPHA", "Step", "find_steps"]
