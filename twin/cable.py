"""The drawstring measurement: cable lengths, residuals and their analytic Jacobian.

The cable runs from the encoder port P_E (fixed, base frame) to the flange centre. For a D-H
error vector X the model length is ``ℓ(X, q) = ‖P(D + X, q) − P_E‖ (+ c)`` and the residual is
``r = ℓ − L`` (paper eq. 1). Optionally the port position (3) and a length offset c (1) — the
unknown zero of the encoder — are unknowns too, appended to X in that order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.kinematics import flange_position, flange_position_jacobian
from twin.units import DH_KEYS, deg_to_rad, mm_to_m

Array = NDArray[np.float64]

DH_BOUND_M = float(mm_to_m(5.0))
"""Search bound on δa, δd (paper: ±5 mm)."""
DH_BOUND_RAD = float(deg_to_rad(8.0))
"""Search bound on δα, δθ (paper: ±8°)."""
PORT_BOUND_M = float(mm_to_m(50.0))
"""Search bound on the port correction when it is estimated."""
OFFSET_BOUND_M = float(mm_to_m(100.0))
"""Search bound on the length offset when it is estimated."""
MAX_POSES = 100_000
"""The most poses a plan, a scenario or a verification may ask for: a typo like 1e9 must be an
error, not an exhausted memory."""


def cable_length(dh: ArrayLike, q_rad: ArrayLike, port_m: ArrayLike) -> Array:
    """Straight-line cable length from the port to the flange centre.

    Args:
        dh: D-H tables, shape (..., 4, n), m and rad.
        q_rad: Joint angles, shape (m, n), rad.
        port_m: Port position in the base frame, shape (3,) or (..., 1, 3), m.

    Returns:
        Lengths, shape (..., m), m.
    """
    return np.linalg.norm(flange_position(dh, q_rad) - np.asarray(port_m), axis=-1)


@dataclass(frozen=True)
class Measurements:
    """Joint angles and measured cable lengths, one row per pose.

    Attributes:
        q_rad: Joint angles, shape (m, n), rad.
        length_m: Measured cable lengths, shape (m,), m.
    """

    q_rad: Array
    length_m: Array

    def __post_init__(self) -> None:
        q = np.array(self.q_rad, dtype=np.float64)
        length = np.array(self.length_m, dtype=np.float64)
        if q.ndim != 2 or length.shape != (q.shape[0],):
            raise ValueError(f"q_rad {q.shape} and length_m {length.shape}: expected (m, n), (m,)")
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(length))):
            raise ValueError("measurements: non-finite values")
        q.setflags(write=False)
        length.setflags(write=False)
        object.__setattr__(self, "q_rad", q)
        object.__setattr__(self, "length_m", length)

    def __len__(self) -> int:
        return int(self.length_m.shape[0])

    def subset(self, rows: ArrayLike) -> Measurements:
        """The measurements at the given row indices."""
        index = np.asarray(rows, dtype=np.intp)
        return Measurements(self.q_rad[index], self.length_m[index])


@dataclass(frozen=True)
class CableModel:
    """Maps an unknown vector x to cable lengths for a nominal robot and port.

    x = (δa1..n, δd1..n, δα1..n, δθ1..n [, δport_x, δport_y, δport_z] [, offset]) in m and rad.

    Attributes:
        dh: Nominal D-H table D, shape (4, n), m and rad.
        port_m: Nominal port position P_E in the base frame, shape (3,), m.
        estimate_port: Whether x carries a port correction.
        estimate_offset: Whether x carries a cable-length offset.
    """

    dh: Array
    port_m: Array
    estimate_port: bool = False
    estimate_offset: bool = False

    def __post_init__(self) -> None:
        dh = np.array(self.dh, dtype=np.float64)
        port = np.array(self.port_m, dtype=np.float64)
        if dh.ndim != 2 or dh.shape[0] != 4 or port.shape != (3,):
            raise ValueError(f"dh {dh.shape}, port_m {port.shape}: expected (4, n), (3,)")
        dh.setflags(write=False)
        port.setflags(write=False)
        object.__setattr__(self, "dh", dh)
        object.__setattr__(self, "port_m", port)

    @property
    def n_dh(self) -> int:
        """Number of D-H unknowns, 4n."""
        return int(self.dh.size)

    @property
    def n_params(self) -> int:
        """Length p of the unknown vector x."""
        return self.n_dh + 3 * self.estimate_port + self.estimate_offset

    @property
    def names(self) -> tuple[str, ...]:
        """Names of the unknowns: ``a1``…``theta6``, then ``port_x``…, ``offset``."""
        n = self.dh.shape[1]
        names = [f"{key}{i}" for key in DH_KEYS for i in range(1, n + 1)]
        if self.estimate_port:
            names += ["port_x", "port_y", "port_z"]
        if self.estimate_offset:
            names.append("offset")
        return tuple(names)

    @property
    def is_length(self) -> Array:
        """Mask of unknowns that are lengths (m) rather than angles (rad), shape (p,)."""
        n = self.dh.shape[1]
        mask = np.r_[np.ones(2 * n), np.zeros(2 * n), np.ones(self.n_params - 4 * n)]
        return mask.astype(bool)

    def bounds(self) -> tuple[Array, Array]:
        """Search box (lower, upper), each shape (p,): ±5 mm / ±8° on the D-H errors."""
        upper = np.where(self.is_length, DH_BOUND_M, DH_BOUND_RAD)
        upper[self.n_dh : self.n_dh + 3 * self.estimate_port] = PORT_BOUND_M
        if self.estimate_offset:
            upper[-1] = OFFSET_BOUND_M
        return -upper, upper

    def split(self, x: ArrayLike) -> tuple[Array, Array, Array]:
        """Unknowns (..., p) to (D-H tables (..., 4, n), ports (..., 1, 3), offsets (..., 1))."""
        x = np.asarray(x, dtype=np.float64)
        if x.shape[-1] != self.n_params:
            raise ValueError(f"x: shape {x.shape}, expected (..., {self.n_params})")
        dh = self.dh + x[..., : self.n_dh].reshape(*x.shape[:-1], *self.dh.shape)
        port = np.broadcast_to(self.port_m, (*x.shape[:-1], 3))
        if self.estimate_port:
            port = port + x[..., self.n_dh : self.n_dh + 3]
        offset = x[..., -1:] if self.estimate_offset else np.zeros((*x.shape[:-1], 1))
        return dh, port[..., None, :], offset

    def lengths(self, x: ArrayLike, q_rad: ArrayLike) -> Array:
        """Model cable lengths ℓ(x, q), shape (..., m), m, for unknowns x of shape (..., p)."""
        dh, port, offset = self.split(x)
        return cable_length(dh, q_rad, port) + offset

    def residuals(self, x: ArrayLike, data: Measurements) -> Array:
        """Residuals r = ℓ(x, q) − L, shape (..., m), m."""
        return self.lengths(x, data.q_rad) - data.length_m

    def jacobian(self, x: ArrayLike, data: Measurements) -> tuple[Array, Array]:
        """Residuals and their analytic Jacobian at one x.

        Args:
            x: Unknowns, shape (p,).
            data: The poses and lengths.

        Returns:
            ``(r, J)``: residuals (m,) in m, Jacobian ∂r/∂x (m, p) in m/m or m/rad.
        """
        dh, port, offset = self.split(x)
        p, dp_dx = flange_position_jacobian(dh, data.q_rad)
        diff = p - port[0]
        distance = np.linalg.norm(diff, axis=-1)
        u = diff / distance[:, None]
        columns = [np.einsum("mk,mkj->mj", u, dp_dx)]
        if self.estimate_port:
            columns.append(-u)
        if self.estimate_offset:
            columns.append(np.ones((len(data), 1)))
        return distance + offset - data.length_m, np.concatenate(columns, axis=1)
