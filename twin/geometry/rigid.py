"""Rigid transforms of 3-D points: rotations from three angles, their derivatives, and the
rigid fit of one point set onto another (Kabsch); rotation vectors (Exp and Log of SO(3)) and
quaternions, with scipy's ``Rotation``, and the Jacobians that carry small turns through them.

Every conversion through scipy's ``Rotation`` is here, and imports it when it runs: importing
``scipy.spatial`` costs about 0.3 s (with the sparse matrices and the trees it loads), a third
of a `twin calibrate` that never turns a rotation vector.

Angles ``(rx, ry, rz)`` compose as ``R = Rz(rz) · Ry(ry) · Rx(rx)`` (rotations about the fixed
x, then y, then z axes). They parametrise small corrections of a frame that is already close
(a tracker frame started from a rigid fit), far from the singularity at ry = ±90°.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from twin.arrays import Array

_IDENTITY = np.eye(3)
_LAST_ROW = np.array([0.0, 0.0, 0.0, 1.0])


def is_rigid_transform(transform: Array) -> bool:
    """Whether a (4, 4) transform is rigid: its rotation R orthonormal (R Rᵀ = I within 1e-9,
    1e-5 relative on the diagonal) and proper (det R > 0), its last row (0, 0, 0, 1) within
    1e-8 (1e-5 relative) — numpy's allclose with those tolerances, at a fifth of its time (a
    study's trial checks three rigs)."""
    rotation = transform[:3, :3]
    (a, b, c), (d, e, f), (g, h, i) = rotation.tolist()
    determinant = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
    return bool(determinant > 0.0
                and np.all(np.abs(rotation @ rotation.T - _IDENTITY) <= 1e-9 + 1e-5 * _IDENTITY)
                and np.all(np.abs(transform[3] - _LAST_ROW) <= 1e-8 + 1e-5 * _LAST_ROW))


def _axis_rotations(angles_rad: ArrayLike) -> Array:
    """Rx, Ry, Rz and their derivatives, stacked: shape (6, ..., 3, 3).

    Each entry written into one zeroed array: a matrix stacked from lists of rows was 0.1 ms
    a call, and a tracker's or a 6-D pose's Jacobian turns its frame three times (two thirds
    of the whole Jacobian's time)."""
    angles = np.asarray(angles_rad, dtype=np.float64)
    c, s = np.cos(angles), np.sin(angles)
    out = np.zeros((6, *angles.shape[:-1], 3, 3))
    # Rotation about axis a turns the plane of the two others (j, k) = (a + 1, a + 2) mod 3.
    for axis in range(3):
        j, k = (axis + 1) % 3, (axis + 2) % 3
        cos, sin = c[..., axis], s[..., axis]
        turn, derivative = out[axis], out[3 + axis]
        turn[..., axis, axis] = 1.0
        turn[..., j, j], turn[..., j, k] = cos, -sin
        turn[..., k, j], turn[..., k, k] = sin, cos
        derivative[..., j, j], derivative[..., j, k] = -sin, -cos
        derivative[..., k, j], derivative[..., k, k] = cos, -sin
    return out


def rotation(angles_rad: ArrayLike) -> Array:
    """``Rz(rz) Ry(ry) Rx(rx)`` of angles (..., 3), rad: shape (..., 3, 3)."""
    rx, ry, rz = _axis_rotations(angles_rad)[:3]
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


def skew(vectors: ArrayLike) -> Array:
    """The cross-product matrices [v]× of vectors (..., 3): shape (..., 3, 3)."""
    v = np.asarray(vectors, dtype=np.float64)
    zero = np.zeros(v.shape[:-1])
    return np.stack([np.stack([zero, -v[..., 2], v[..., 1]], axis=-1),
                     np.stack([v[..., 2], zero, -v[..., 0]], axis=-1),
                     np.stack([-v[..., 1], v[..., 0], zero], axis=-1)], axis=-2)


def exp_rotation(vectors_rad: ArrayLike) -> Array:
    """The rotations Exp(φ) of rotation vectors (..., 3), rad (axis times angle): shape
    (..., 3, 3)."""
    from scipy.spatial.transform import Rotation

    v = np.array(vectors_rad, dtype=np.float64)  # a copy: scipy refuses read-only buffers
    return np.asarray(Rotation.from_rotvec(v.reshape(-1, 3)).as_matrix()
                      .reshape(*v.shape[:-1], 3, 3), dtype=np.float64)


def log_rotation(matrices: ArrayLike) -> Array:
    """The rotation vectors Log(R) of rotations (..., 3, 3): shape (..., 3), rad, each of angle
    at most π."""
    from scipy.spatial.transform import Rotation

    r = np.array(matrices, dtype=np.float64)  # a copy: scipy refuses read-only buffers
    return np.asarray(Rotation.from_matrix(r.reshape(-1, 3, 3)).as_rotvec()
                      .reshape(*r.shape[:-2], 3), dtype=np.float64)


def rotation_angle(matrices: ArrayLike) -> Array:
    """The angle of each rotation (..., 3, 3), rad in [0, π]: shape (...)."""
    from scipy.spatial.transform import Rotation

    r = np.array(matrices, dtype=np.float64)  # a copy: scipy refuses read-only buffers
    return np.asarray(Rotation.from_matrix(r.reshape(-1, 3, 3)).magnitude()
                      .reshape(r.shape[:-2]), dtype=np.float64)


def quaternion_rotation(quaternions_wxyz: ArrayLike) -> Array:
    """The rotations of quaternions (..., 4), scalar first (normalised first): shape
    (..., 3, 3)."""
    from scipy.spatial.transform import Rotation

    q = np.array(quaternions_wxyz, dtype=np.float64)
    return np.asarray(Rotation.from_quat(q.reshape(-1, 4), scalar_first=True).as_matrix()
                      .reshape(*q.shape[:-1], 3, 3), dtype=np.float64)


def rotation_quaternion(matrices: ArrayLike) -> Array:
    """Unit quaternions (..., 4), scalar first, of rotations (..., 3, 3); each of the two signs
    of a turn is as scipy gives it (the caller picks one)."""
    from scipy.spatial.transform import Rotation

    r = np.array(matrices, dtype=np.float64)
    return np.asarray(Rotation.from_matrix(r.reshape(-1, 3, 3)).as_quat(scalar_first=True)
                      .reshape(*r.shape[:-2], 4), dtype=np.float64)


SMALL_ANGLE_RAD = 1e-6
"""Below this angle the Jacobians of Exp and Log take their series (their closed forms divide
by the angle)."""


def _angle_terms(vectors_rad: Array) -> tuple[Array, Array, Array]:
    """θ, [φ]× and [φ]×² of rotation vectors (..., 3)."""
    angle = np.linalg.norm(vectors_rad, axis=-1)
    cross = skew(vectors_rad)
    return angle, cross, cross @ cross


def right_jacobian(vectors_rad: ArrayLike) -> Array:
    """J_r(φ) of rotation vectors (..., 3): Exp(φ + δ) ≈ Exp(φ) Exp(J_r(φ) δ); shape
    (..., 3, 3)."""
    angle, cross, square = _angle_terms(np.asarray(vectors_rad, dtype=np.float64))
    small = angle < SMALL_ANGLE_RAD
    theta = np.where(small, 1.0, angle)
    first = np.where(small, 0.5, (1.0 - np.cos(theta)) / theta**2)
    second = np.where(small, 1.0 / 6.0, (theta - np.sin(theta)) / theta**3)
    return np.asarray(np.eye(3) - first[..., None, None] * cross
                      + second[..., None, None] * square, dtype=np.float64)


def left_jacobian_inverse(vectors_rad: ArrayLike) -> Array:
    """J_l⁻¹(φ) of rotation vectors (..., 3): Log(Exp(δ) Exp(φ)) ≈ φ + J_l⁻¹(φ) δ; shape
    (..., 3, 3)."""
    angle, cross, square = _angle_terms(np.asarray(vectors_rad, dtype=np.float64))
    small = angle < SMALL_ANGLE_RAD
    theta = np.where(small, 1.0, angle)
    second = np.where(small, 1.0 / 12.0,
                      1.0 / theta**2 - (1.0 + np.cos(theta)) / (2.0 * theta * np.sin(theta)))
    return np.asarray(np.eye(3) - 0.5 * cross + second[..., None, None] * square,
                      dtype=np.float64)


def mean_rotation(matrices: ArrayLike) -> Array:
    """The chordal L2 mean of rotations (k, 3, 3): the rotation nearest their sum (the SVD
    projection, a proper rotation), shape (3, 3)."""
    u, _, vt = np.linalg.svd(np.sum(np.asarray(matrices, dtype=np.float64), axis=0))
    flip = np.diag([1.0, 1.0, 1.0 if np.linalg.det(u @ vt) > 0 else -1.0])
    return np.asarray(u @ flip @ vt, dtype=np.float64)
