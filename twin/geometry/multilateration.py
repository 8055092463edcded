"""Where a fixed point is, from its distances to known points: multilateration.

A drawstring encoder's port nobody measured is such a point: the nominal robot puts the
measured point at p_i for each pose, the encoder reads L_i ≈ ‖p_i − P‖ (+ an unknown zero c of
the encoder, when it is estimated: one per capture session when the data have several).
Squaring removes the root:

    ‖p_i‖² − 2 p_iᵀ P + ‖P‖² = (L_i + c)²,

linear in (P, ‖P‖²) when c is known — a least-squares solve for the start (Fang's linearisation,
with ‖P‖² a fourth unknown) — then Gauss–Newton on the distances themselves refines P (and c).
The nominal robot's errors (millimetres) leave the start millimetres off: a calibration then
takes it from there. Four poses not on one plane determine P; the solve says so when they do
not (a rank below the unknowns').
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from twin.arrays import Array

REFINE_ITERATIONS = 20
"""Gauss–Newton steps of the refinement."""
RANK_RTOL = 1e-9
"""Singular values below this fraction of the largest leave a direction undetermined."""


class Multilateration(NamedTuple):
    """A point found from distances."""

    point_m: Array
    """The point, shape (3,), m."""
    offsets_m: Array
    """The distances' common offset c of each group of rows, shape (g,), m (g = 0 without
    offsets)."""
    rms_m: float
    """RMS of the distance residuals at the point, m."""
    determined: bool
    """Whether the points determine it (their geometry is not degenerate)."""


def _linear_start(points_m: Array, distances_m: Array) -> tuple[Array, bool]:
    """The least-squares solution of ‖p‖² − 2 pᵀP + w = L² for (P, w): the start."""
    design = np.column_stack([-2.0 * points_m, np.ones(len(points_m))])
    target = distances_m**2 - np.sum(points_m**2, axis=1)
    solution, _, rank, singular = np.linalg.lstsq(design, target, rcond=None)
    determined = rank == 4 and singular[-1] > RANK_RTOL * singular[0]
    return np.asarray(solution[:3], dtype=np.float64), bool(determined)


def multilaterate(points_m: ArrayLike, distances_m: ArrayLike, *,
                  offsets: ArrayLike | None = None) -> Multilateration:
    """The point at the given distances from the points (module docstring).

    Args:
        points_m: Known points, shape (m, 3), m.
        distances_m: Their measured distances to the point, shape (m,), m.
        offsets: Which unknown common offset c_g each distance shares (L_i + c_g = ‖p_i − P‖),
            an index per row, shape (m,); the offsets are found with the point (the start
            takes them 0). None: the distances are exact.

    Raises:
        ValueError: for fewer points than the unknowns, or shapes that differ.
    """
    points = np.asarray(points_m, dtype=np.float64)
    distances = np.asarray(distances_m, dtype=np.float64)
    group = np.zeros(len(distances), dtype=np.intp) if offsets is None \
        else np.asarray(offsets, dtype=np.intp)
    shares = np.eye(int(group.max(initial=-1)) + 1)[group] if offsets is not None \
        else np.zeros((len(distances), 0))
    unknowns = 3 + shares.shape[1]
    if points.ndim != 2 or points.shape[1] != 3 or distances.shape != (len(points),) \
            or group.shape != distances.shape or len(points) < unknowns + 1:
        raise ValueError(f"points (m, 3), distances and offsets (m,), m > {unknowns}: got "
                         f"{points.shape}, {distances.shape} and {group.shape}")
    point, determined = _linear_start(points, distances)
    c = np.zeros(shares.shape[1])
    for _ in range(REFINE_ITERATIONS):
        towards = point - points
        reach = np.linalg.norm(towards, axis=1)
        jacobian = np.column_stack([towards / np.maximum(reach, 1e-12)[:, None], -shares])
        step = np.linalg.lstsq(jacobian, -(reach - distances - shares @ c), rcond=None)[0]
        point, c = point + step[:3], c + step[3:]
        if np.linalg.norm(step) <= 1e-13 * max(float(np.linalg.norm(point)), 1.0):
            break
    residuals = np.linalg.norm(point - points, axis=1) - distances - shares @ c
    return Multilateration(point, c, float(np.sqrt(np.mean(residuals**2))), determined)


__all__ = ["Multilateration", "multilaterate"]
