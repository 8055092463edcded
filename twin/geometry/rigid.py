"""Rigid transforms of 3-D points: rotations from three angles, their derivatives, and the
rigid fit of one point set onto another (Kabsch).

Angles ``(rx, ry, rz)`` compose as ``R = Rz(rz) · Ry(ry) · Rx(rx)`` (rotations about the fixed
x, then y, then z axes). They parametrise small corrections of a frame that is already close
(a tracker frame started from a rigid fit), far from the singularity at ry = ±90°.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from twin.arrays import Array


def _axis_rotations(angles_rad: ArrayLike) -> tuple[Array, Array, Array, Array, Array, Array]:
    """Rx, Ry, Rz and their derivatives, each shape (..., 3, 3)."""
    angles = np.asarray(angles_rad, dtype=np.float64)
    c, s = np.cos(angles), np.sin(angles)
    zero, one = np.zeros(angles.shape[:-1]), np.ones(angles.shape[:-1])

    def matrix(rows: list[list[Array]]) -> Array:
        return np.stack([np.stack(row, axis=-1) for row in rows], axis=-2)

    cx, cy, cz = c[..., 0], c[..., 1], c[..., 2]
    sx, sy, sz = s[..., 0], s[..., 1], s[..., 2]
    rx = matrix([[one, zero, zero], [zero, cx, -sx], [zero, sx, cx]])
    ry = matrix([[cy, zero, sy], [zero, one, zero], [-sy, zero, cy]])
    rz = matrix([[cz, -sz, zero], [sz, cz, zero], [zero, zero, one]])
    drx = matrix([[zero, zero, zero], [zero, -sx, -cx], [zero, cx, -sx]])
    dry = matrix([[-sy, zero, cy], [zero, zero, zero], [-cy, zero, -sy]])
    drz = matrix([[-sz, -cz, zero], [cz, -sz, zero], [zero, zero, zero]])
    return rx, ry, rz, drx, dry, drz


def rotation(angles_rad: ArrayLike) -> Array:
    """``Rz(rz) Ry(ry) Rx(rx)`` of angles (..., 3), rad: shape (..., 3, 3)."""
    rx, ry, rz, *_ = _axis_rotations(angles_rad)
    return np.asarray(rz @ ry @ rx, dtype=np.float64)


def rotation_derivatives(angles_rad: ArrayLike) -> Array:
    """∂R/∂(rx, ry, rz) of :func:`rotation` at angles (3,): shape (3, 3, 3), the first index the
    angle."""
    rx, ry, rz, drx, dry, drz = _axis_rotations(angles_rad)
    return np.stack([rz @ ry @ drx, rz @ dry @ rx, drz @ ry @ rx])


def angles(rotation_matrix: ArrayLike) -> Array:
    """The angles (rx, ry, rz), rad, of a rotation matrix (3, 3) away from ry = ±90°: shape (3,).
    """
    r = np.asarray(rotation_matrix, dtype=np.float64)
    return np.array([np.arctan2(r[2, 1], r[2, 2]),
                     np.arctan2(-r[2, 0], np.hypot(r[2, 1], r[2, 2])),
                     np.arctan2(r[1, 0], r[0, 0])])


def transform(translation_m: ArrayLike, angles_rad: ArrayLike) -> Array:
    """The 4×4 transform of a translation (3,), m, and angles (3,), rad."""
    matrix = np.eye(4)
    matrix[:3, :3] = rotation(angles_rad)
    matrix[:3, 3] = np.asarray(translation_m, dtype=np.float64)
    return matrix


class RigidFit(NamedTuple):
    """The rigid motion that best carries one point set onto another."""

    transform: Array
    """4×4 transform, m: ``target ≈ R · source + t``."""
    rms_m: float
    """RMS distance between the carried source points and the target points, m."""


def kabsch(source_m: ArrayLike, target_m: ArrayLike) -> RigidFit:
    """Least-squares rigid fit of ``source`` onto ``target`` (Kabsch 1976), both shape (m, 3).

    The rotation is the orthogonal Procrustes solution from the SVD of the centred cross
    covariance, with the sign of the last singular vector flipped if needed so that it is a
    proper rotation (det = +1), never a reflection.

    Raises:
        ValueError: for fewer than three points or point sets of different shapes.
    """
    source = np.asarray(source_m, dtype=np.float64)
    target = np.asarray(target_m, dtype=np.float64)
    if source.shape != target.shape or source.ndim != 2 or source.shape[1] != 3 \
            or len(source) < 3:
        raise ValueError(f"kabsch: point sets {source.shape} and {target.shape}, expected the "
                         "same (m, 3) with m >= 3")
    source_centre, target_centre = source.mean(axis=0), target.mean(axis=0)
    u, _, vt = np.linalg.svd((source - source_centre).T @ (target - target_centre))
    flip = np.diag([1.0, 1.0, 1.0 if np.linalg.det(vt.T @ u.T) > 0 else -1.0])
    r = vt.T @ flip @ u.T
    matrix = np.eye(4)
    matrix[:3, :3] = r
    matrix[:3, 3] = target_centre - r @ source_centre
    carried = source @ r.T + matrix[:3, 3]
    return RigidFit(matrix, float(np.sqrt(np.mean(np.sum((carried - target) ** 2, axis=1)))))
