"""BIPSO's B-spline step compiled with numba (optional extra ``fast``): the cubic curve through
the particles, sampled at evenly spaced parameters, in one pass.

The curve is the one :func:`scipy.interpolate.make_interp_spline` builds with k = 3 (the
reference, and the path taken without numba: :func:`twin.solvers.swarm.interpolated_points`):
the cubic spline that interpolates N ≥ 4 points with not-a-knot ends is unique, so its B-spline
form and the piecewise Hermite form used here are one function. Here it is found from its
slopes s_i at the parameters t_i (de Boor, *A Practical Guide to Splines*, ch. IV: the
tridiagonal system of C² continuity, with the not-a-knot end rows of
:class:`scipy.interpolate.CubicSpline`), solved by elimination without pivoting — every
interior row is diagonally dominant — and evaluated piece by piece. scipy spends some 90 µs of
checks and wrappers on a curve through 100 particles in 24 unknowns; this takes 6 µs, equal to
round-off (tests/test_swarm.py). Compiled once and cached on disk (``cache=True``).
"""

from __future__ import annotations

import numba
import numpy as np

from twin.arrays import Array


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _slopes(t: Array, y: Array) -> Array:
    """The slopes s (n, p) of the not-a-knot cubic spline through (t_i, y_i), n ≥ 4."""
    n, p = y.shape
    dx = t[1:] - t[:-1]
    slope = np.empty((n - 1, p))
    for i in range(n - 1):
        for j in range(p):
            slope[i, j] = (y[i + 1, j] - y[i, j]) / dx[i]
    lower, diagonal, upper = np.zeros(n), np.empty(n), np.zeros(n)
    b = np.empty((n, p))
    # First row: the third derivative continuous at t_1 (t_1 is no knot).
    span = t[2] - t[0]
    diagonal[0], upper[0] = dx[1], span
    for j in range(p):
        b[0, j] = ((dx[0] + 2.0 * span) * dx[1] * slope[0, j]
                   + dx[0] ** 2 * slope[1, j]) / span
    for i in range(1, n - 1):  # C² at every interior t_i
        lower[i], diagonal[i], upper[i] = dx[i], 2.0 * (dx[i - 1] + dx[i]), dx[i - 1]
        for j in range(p):
            b[i, j] = 3.0 * (dx[i] * slope[i - 1, j] + dx[i - 1] * slope[i, j])
    # Last row: the third derivative continuous at t_{n−2}.
    span = t[n - 1] - t[n - 3]
    lower[n - 1], diagonal[n - 1] = span, dx[n - 3]
    for j in range(p):
        b[n - 1, j] = (dx[n - 2] ** 2 * slope[n - 3, j]
                       + (2.0 * span + dx[n - 2]) * dx[n - 3] * slope[n - 2, j]) / span
    for i in range(1, n):
        factor = lower[i] / diagonal[i - 1]
        diagonal[i] -= factor * upper[i - 1]
        for j in range(p):
            b[i, j] -= factor * b[i - 1, j]
    s = np.empty((n, p))
    for j in range(p):
        s[n - 1, j] = b[n - 1, j] / diagonal[n - 1]
    for i in range(n - 2, -1, -1):
        for j in range(p):
            s[i, j] = (b[i, j] - upper[i] * s[i + 1, j]) / diagonal[i]
    return s


@numba.njit(cache=True, nogil=True, error_model="numpy")
def curve_points(t: Array, y: Array, at: Array) -> Array:
    """The cubic not-a-knot spline through the points y (n, p) at parameters t (n,), strictly
    increasing, n ≥ 4, evaluated at the parameters ``at`` (M,), ascending within [t_0, t_{n−1}]:
    shape (M, p)."""
    n, p = y.shape
    s = _slopes(t, y)
    out = np.empty((at.size, p))
    piece = 0
    for k in range(at.size):
        while piece < n - 2 and at[k] > t[piece + 1]:
            piece += 1
        h = t[piece + 1] - t[piece]
        u = (at[k] - t[piece]) / h
        # The cubic Hermite basis on the piece, its slopes scaled by the piece's length.
        h00, h10 = (1.0 + 2.0 * u) * (1.0 - u) ** 2, u * (1.0 - u) ** 2 * h
        h01, h11 = u * u * (3.0 - 2.0 * u), u * u * (u - 1.0) * h
        for j in range(p):
            out[k, j] = (h00 * y[piece, j] + h10 * s[piece, j] + h01 * y[piece + 1, j]
                         + h11 * s[piece + 1, j])
    return out
