"""Forward kinematics of standard D-H chains, vectorised over poses and over tables.

Every function takes a D-H table ``dh`` of shape (..., 4, n) — rows a [m], d [m], alpha [rad],
theta offset [rad]; any leading dimensions are a batch of K candidate tables — and joint angles
``q_rad`` of shape (m, n) or (..., m, n). Results carry the batch dimensions in front, then the
pose dimension m. Joint i contributes ``Rz(q_i + theta_i) · Tz(d_i) · Tx(a_i) · Rx(alpha_i)``.

The chain is walked joint by joint (n steps, each a handful of elementwise array operations on
all tables and poses at once), carrying the frame's origin and its x, y, z axes; no 4×4 matrix
products and no loop over poses or tables.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]


class Chain(NamedTuple):
    """Frames 0..n of a chain for a batch of tables and poses.

    Attributes:
        origins: Frame origins o_0..o_n in the base frame, shape (..., m, n+1, 3), m.
        x_axes: Frame x axes, shape (..., m, n+1, 3), unit vectors.
        y_axes: Frame y axes, shape (..., m, n+1, 3), unit vectors.
        z_axes: Frame z axes, shape (..., m, n+1, 3), unit vectors.
    """

    origins: Array
    x_axes: Array
    y_axes: Array
    z_axes: Array


def _angles(dh: Array, q_rad: Array) -> tuple[Array, ...]:
    """Broadcast the table against the poses: six arrays of shape (..., m, n)."""
    a, d, alpha, theta = (dh[..., k, None, :] for k in range(4))
    joint = q_rad + theta
    shape = np.broadcast_shapes(joint.shape, a.shape)
    return tuple(
        np.broadcast_to(v, shape)
        for v in (a, d, np.cos(alpha), np.sin(alpha), np.cos(joint), np.sin(joint))
    )


def _check_shapes(dh: Array, q_rad: Array) -> None:
    if dh.ndim < 2 or dh.shape[-2] != 4:
        raise ValueError(f"dh: shape {dh.shape}, expected (..., 4, n)")
    if q_rad.ndim < 2 or q_rad.shape[-1] != dh.shape[-1]:
        raise ValueError(f"q_rad: shape {q_rad.shape}, expected (..., m, {dh.shape[-1]})")


def _joint_major(array: Array, ndim: int) -> Array:
    """(batch..., m, n) to (n, 1..., batch..., m) with ``ndim`` dimensions, for broadcasting."""
    moved = np.moveaxis(array, -1, 0)
    return moved.reshape(moved.shape[0], *(1,) * (ndim - moved.ndim), *moved.shape[1:])


def _walk(dh: ArrayLike, q_rad: ArrayLike, keep: bool) -> list[tuple[Array, ...]]:
    """Frames (origin, x, y, z) after each joint; only the last one unless ``keep``."""
    dh = np.asarray(dh, dtype=np.float64)
    q_rad = np.asarray(q_rad, dtype=np.float64)
    _check_shapes(dh, q_rad)
    a, d, ca, sa, ct, st = _angles(dh, q_rad)
    batch = a.shape[:-1]
    origin = np.zeros((*batch, 3))
    x = np.broadcast_to(np.array([1.0, 0.0, 0.0]), (*batch, 3))
    y = np.broadcast_to(np.array([0.0, 1.0, 0.0]), (*batch, 3))
    z = np.broadcast_to(np.array([0.0, 0.0, 1.0]), (*batch, 3))
    frames: list[tuple[Array, ...]] = [(origin, x, y, z)]
    for i in range(dh.shape[-1]):
        cti, sti, cai, sai = ct[..., i, None], st[..., i, None], ca[..., i, None], sa[..., i, None]
        x_rot = cti * x + sti * y
        y_rot = cti * y - sti * x
        origin = origin + d[..., i, None] * z + a[..., i, None] * x_rot
        y, z = cai * y_rot + sai * z, cai * z - sai * y_rot
        x = x_rot
        if keep:
            frames.append((origin, x, y, z))
        else:
            frames[0] = (origin, x, y, z)
    return frames


def flange_position(dh: ArrayLike, q_rad: ArrayLike) -> Array:
    """Flange centre in the base frame.

    Args:
        dh: D-H tables, shape (..., 4, n), m and rad.
        q_rad: Joint angles, shape (m, n) or (..., m, n), rad.

    Returns:
        base_p_flange, shape (..., m, 3), m.
    """
    # The hot path of the swarms: instead of carrying whole frames (12 components) base to
    # flange, carry one point flange to base, p ← Rz(θ_i)·Rx(α_i)·p + (a_i cos θ_i,
    # a_i sin θ_i, d_i), on joint-major contiguous arrays. About 3× less memory traffic.
    dh = np.asarray(dh, dtype=np.float64)
    q_rad = np.asarray(q_rad, dtype=np.float64)
    _check_shapes(dh, q_rad)
    ndim = max(dh.ndim, q_rad.ndim)  # of (n, batch..., m) once joint-major
    a, d, alpha, theta = (_joint_major(dh[..., k, None, :], ndim) for k in range(4))
    q_joint_major = _joint_major(q_rad, ndim)
    # cos/sin of q + θ by the angle-sum identities: the transcendentals then run on the poses
    # (n, m) and the tables (n, ...) separately instead of on every (table, pose) pair, which
    # made them most of a swarm evaluation's time.
    cq, sq = np.cos(q_joint_major), np.sin(q_joint_major)
    cth, sth = np.cos(theta), np.sin(theta)
    ct, st = cq * cth - sq * sth, sq * cth + cq * sth  # (n, ..., m)
    ca, sa = np.cos(alpha), np.sin(alpha)
    px, py = a[-1] * ct[-1], a[-1] * st[-1]
    pz = np.broadcast_to(d[-1], px.shape)
    for i in range(ct.shape[0] - 2, -1, -1):
        wy = ca[i] * py - sa[i] * pz
        wz = sa[i] * py + ca[i] * pz
        u = px + a[i]
        px, py, pz = ct[i] * u - st[i] * wy, st[i] * u + ct[i] * wy, wz + d[i]
    return np.stack([px, py, pz], axis=-1)


def _homogeneous(origin: Array, x: Array, y: Array, z: Array) -> Array:
    """4×4 transforms, shape (..., 4, 4), from origins and axes of shape (..., 3)."""
    transform = np.zeros((*origin.shape[:-1], 4, 4))
    transform[..., :3, 0], transform[..., :3, 1], transform[..., :3, 2] = x, y, z
    transform[..., :3, 3] = origin
    transform[..., 3, 3] = 1.0
    return transform


def flange_transform(dh: ArrayLike, q_rad: ArrayLike) -> Array:
    """Homogeneous flange pose in the base frame, base_T_flange, shape (..., m, 4, 4), m."""
    return _homogeneous(*_walk(dh, q_rad, keep=False)[-1])


def chain(dh: ArrayLike, q_rad: ArrayLike) -> Chain:
    """All frames 0..n (base to flange) for drawing a robot or differentiating its chain."""
    frames = _walk(dh, q_rad, keep=True)
    return Chain(*(np.stack(parts, axis=-2) for parts in zip(*frames, strict=True)))


def flange_position_jacobian(dh: ArrayLike, q_rad: ArrayLike) -> tuple[Array, Array]:
    """Flange position and its analytic Jacobian w.r.t. the D-H table.

    For revolute z axes: ∂P/∂θ_i = z_{i−1} × (P − o_{i−1}), ∂P/∂d_i = z_{i−1}, ∂P/∂a_i = x_i,
    ∂P/∂α_i = x_i × (P − o_i). The θ block is also the joint Jacobian ∂P/∂q.

    Args:
        dh: D-H tables, shape (..., 4, n), m and rad.
        q_rad: Joint angles, shape (m, n) or (..., m, n), rad.

    Returns:
        ``(base_p_flange, jacobian)``: shapes (..., m, 3) in m and (..., m, 3, 4n) with columns
        ordered (a1..an, d1..dn, α1..αn, θ1..θn), in m/m and m/rad.
    """
    frames = chain(dh, q_rad)
    p = frames.origins[..., -1:, :]
    o_prev, z_prev = frames.origins[..., :-1, :], frames.z_axes[..., :-1, :]
    o_next, x_next = frames.origins[..., 1:, :], frames.x_axes[..., 1:, :]
    blocks = (
        x_next,
        z_prev,
        np.cross(x_next, p - o_next),
        np.cross(z_prev, p - o_prev),
    )
    jacobian = np.concatenate(blocks, axis=-2)  # (..., m, 4n, 3)
    return p[..., 0, :], np.swapaxes(jacobian, -1, -2)


def flange_jacobian(dh: ArrayLike, q_rad: ArrayLike) -> tuple[Array, Array]:
    """Flange pose and its geometric joint Jacobian, for inverse kinematics.

    Column i is ``(z_{i−1} × (P − o_{i−1}), z_{i−1})``: the flange's linear velocity (m/rad) and
    angular velocity (rad/rad) in the base frame per unit rate of joint i.

    Args:
        dh: D-H tables, shape (..., 4, n), m and rad.
        q_rad: Joint angles, shape (m, n) or (..., m, n), rad.

    Returns:
        ``(base_T_flange, jacobian)``: shapes (..., m, 4, 4) in m and (..., m, 6, n), rows
        (vx, vy, vz, wx, wy, wz).
    """
    frames = chain(dh, q_rad)
    last = tuple(part[..., -1, :] for part in frames)
    z_prev = frames.z_axes[..., :-1, :]
    linear = np.cross(z_prev, frames.origins[..., -1:, :] - frames.origins[..., :-1, :])
    jacobian = np.concatenate([linear, z_prev], axis=-1)  # (..., m, n, 6)
    return _homogeneous(*last), np.swapaxes(jacobian, -1, -2)
