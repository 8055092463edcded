"""The swarms' steps compiled with numba (optional extra ``fast``): BIPSO's cubic curve through
the particles, sampled at evenly spaced parameters, in one pass; an iteration's moves of PSO and
BIPSO (:func:`pso_candidates`) and the selection after it (:func:`keep_best`) in one call each,
where numpy spent some 150 µs per iteration on a dozen small array operations (the random
numbers stay numpy's, drawn by the caller from the run's generator in the same order).

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

import math

import numba
import numpy as np
from numpy.typing import NDArray

from twin.arrays import Array


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _slopes(t: Array, y: Array) -> Array:
    """The slopes s (n, p) of the not-a-knot cubic spline through (t_i, y_i), n ≥ 4."""
    n, p = y.shape
    dx = np.empty(n - 1)
    slope = np.empty((n - 1, p))
    for i in range(n - 1):
        dx[i] = t[i + 1] - t[i]
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


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _chords(x: Array, rtol: float) -> tuple[Array, NDArray[np.intp]]:
    """:func:`twin.solvers.swarm.chord_parameters` in one pass: the chord-length parameters
    (K,) in [0, 1] and the indices (K,) of the particles x (N, p) they belong to."""
    n, p = x.shape
    chords = np.empty(n - 1)
    total = 0.0
    for i in range(n - 1):
        square = 0.0
        for j in range(p):
            step = x[i + 1, j] - x[i, j]
            square += step * step
        chords[i] = math.sqrt(square)
        total += chords[i]
    kept = np.empty(n, dtype=np.intp)
    t = np.empty(n)
    kept[0], t[0], size = 0, 0.0, 1
    for i in range(n - 1):
        if chords[i] > rtol * total:
            kept[size], t[size] = i + 1, t[size - 1] + chords[i]
            size += 1
    if t[size - 1] > 0:
        for i in range(size):
            t[i] /= t[size - 1]
    return t[:size], kept[:size]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _copy_row(source: Array, i: int, target: Array, k: int) -> None:
    """target[k] = source[i], element by element: a row assignment costs numba seconds of
    compiling (keep_best's took 8 of a fresh install's 36 s), a loop a tenth of that."""
    for j in range(source.shape[1]):
        target[k, j] = source[i, j]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def pso_candidates(x: Array, v: Array, best_x: Array, g_x: Array, r: Array, omega: float,
                   coefficients: Array, vmax: Array, lower: Array, upper: Array, at: Array,
                   rtol: float) -> tuple[Array, bool]:
    """One iteration's moves of PSO and BIPSO (:func:`twin.solvers.swarm.particle_swarm`):
    eq. 18's velocity, clamped, written into ``v`` (N, p); the moved particles clipped to the
    box; and, if ``at`` holds M parameters, the cubic curve through them by chord length at
    those parameters, clipped.

    Args:
        x, v, best_x: Positions, velocities, personal bests, (N, p). g_x: Global best, (p,).
        r: r1 and r2, shape (2, N, p), drawn by the caller from the run's generator.
        omega: Inertia weight. coefficients: (c1, c2). vmax: Velocity clamp, (p,).
        lower, upper: The box, (p,). at: Curve parameters, (M,) (none for PSO).
        rtol: Chords shorter than this share of the total are dropped (duplicate particles).

    Returns:
        ``(candidates, drawn)``: shape (N + M, p), the moved particles then the curve's points;
        ``drawn`` False when fewer than four distinct particles leave the curve to a lower
        degree (rows N onwards are then unset: the caller draws them with scipy).
    """
    n, p = x.shape
    out = np.empty((n + at.size, p))
    for i in range(n):
        for j in range(p):
            # The same operations in the same order as numpy's (no contraction): equal bits.
            velocity = (omega * v[i, j] + coefficients[0] * r[0, i, j] * (best_x[i, j] - x[i, j])
                        + coefficients[1] * r[1, i, j] * (g_x[j] - x[i, j]))
            velocity = min(max(velocity, -vmax[j]), vmax[j])
            v[i, j] = velocity
            out[i, j] = min(max(x[i, j] + velocity, lower[j]), upper[j])
    if at.size == 0:
        return out, True
    t, kept = _chords(out[:n], rtol)
    if t.size < 4:
        return out, False
    through = np.empty((kept.size, p))
    for i in range(kept.size):
        _copy_row(out, kept[i], through, i)
    points = curve_points(t, through, at)
    for i in range(at.size):
        for j in range(p):
            out[n + i, j] = min(max(points[i, j], lower[j]), upper[j])
    return out, True


@numba.njit(cache=True, nogil=True, error_model="numpy")
def keep_best(candidates: Array, f: Array, chosen: NDArray[np.intp], x: Array, best_x: Array,
              best_f: Array) -> None:
    """:func:`twin.solvers.swarm.best_in_slots` and the elitist personal-best update in place.

    Args:
        candidates: Positions (K, p); the first N are the slots' moved particles.
        f: Their objective, (K,).
        chosen: The best N candidates, best first (a stable argsort's first N), (N,).
        x: The slots' positions (N, p), overwritten by the survivors.
        best_x, best_f: Personal bests (N, p) and their f (N,), updated where improved.
    """
    n = x.shape[0]
    survives = np.zeros(n, dtype=np.bool_)
    for c in chosen:
        if c < n:
            survives[c] = True
    fx = np.empty(n)
    for i in range(n):
        fx[i] = f[i]
        _copy_row(candidates, i, x, i)
    slot = 0
    for c in chosen:  # newcomers, best first, take the freed slots in index order
        if c >= n:
            while survives[slot]:
                slot += 1
            _copy_row(candidates, c, x, slot)
            fx[slot] = f[c]
            slot += 1
    for i in range(n):
        if fx[i] < best_f[i]:
            _copy_row(x, i, best_x, i)
            best_f[i] = fx[i]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _free_minimiser(A: Array, gradient: Array, h: Array, free: NDArray[np.bool_]) -> Array:
    """The minimiser of ½hᵀAh + gᵀh over the free unknowns, the held ones fixed at h: the
    solution of A_ff z = −(g_f + A_fh h_h), shape (free,)."""
    index = np.nonzero(free)[0]
    held = np.nonzero(~free)[0]
    k = index.size
    system = np.empty((k, k))
    rhs = np.empty(k)
    for a in range(k):
        row = index[a]
        total = gradient[row]
        for j in held:
            total += A[row, j] * h[j]
        rhs[a] = -total
        for b in range(k):
            system[a, b] = A[row, index[b]]
    return np.asarray(np.linalg.solve(system, rhs), dtype=np.float64)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def box_step(A: Array, gradient: Array, low: Array, high: Array, rtol: float) -> Array:
    """BVLS on ½hᵀAh + gᵀh with low ≤ h ≤ high, step for step the algorithm of
    :func:`twin.solvers.lm.boxed_damped_step` (the reference, and the path without numba),
    whose Python overhead per small solve was nine tenths of its time; shape (p,).

    Args:
        A: JᵀJ + diag(damping), positive definite, shape (p, p). gradient: Jᵀr, shape (p,).
        low, high: The step's limits, shape (p,), low ≤ 0 ≤ high.
        rtol: A held unknown is released only when pushed inwards by more than this fraction
            of the gradient's size (:data:`twin.solvers.lm.BOX_RTOL`).
    """
    p = gradient.size
    h = np.zeros(p)
    side = np.zeros(p, dtype=np.int8)  # −1 held at low, +1 held at high, 0 free
    free = np.ones(p, dtype=np.bool_)
    while free.any():
        index = np.nonzero(free)[0]
        z = _free_minimiser(A, gradient, h, free)
        out = False
        for a in range(index.size):
            i = index[a]
            h[i] = min(max(z[a], low[i]), high[i])
            if z[a] < low[i] or z[a] > high[i]:
                side[i] = -1 if z[a] < low[i] else 1
                free[i] = False
                out = True
        if not out:
            break
    for _ in range(p):
        pulled = A @ h
        push = np.empty(p)
        for j in range(p):  # > 0 where the bound holds against descent
            push[j] = (pulled[j] + gradient[j]) * side[j]
        k = int(np.argmax(push))
        size = abs(gradient[k])
        for j in range(p):
            size += abs(A[k, j]) * abs(h[j])
        if push[k] <= rtol * size:
            break
        side[k] = 0
        while True:
            free = side == 0
            if not free.any():
                break
            index = np.nonzero(free)[0]
            z = _free_minimiser(A, gradient, h, free)
            now = np.empty(index.size)
            fraction = np.empty(index.size)
            blocked = False
            for a in range(index.size):
                i = index[a]
                now[a] = h[i]
                fraction[a] = np.inf
                if z[a] < low[i] or z[a] > high[i]:
                    limit = low[i] if z[a] < low[i] else high[i]
                    fraction[a] = (limit - now[a]) / (z[a] - now[a])
                    blocked = True
            if not blocked:
                for a in range(index.size):
                    h[index[a]] = z[a]
                break
            first = int(np.argmin(fraction))
            i = index[first]
            below = z[first] < low[i]
            for a in range(index.size):
                h[index[a]] = now[a] + fraction[first] * (z[a] - now[a])
            h[i] = low[i] if below else high[i]
            side[i] = -1 if below else 1
    for j in range(p):
        h[j] = min(max(h[j], low[j]), high[j])
    return h


def load() -> None:
    """Load (on a fresh install, compile) every kernel of this module, as the solvers call them:
    fresh float64 arrays in C order, the curve's parameters read-only as
    :func:`twin.solvers.swarm._even` keeps them (PSO's empty set too). A study's process calls
    it before its first trial, so that no method's time includes numba's loading: the first LM
    step that left the box took 13–20 ms more in each worker, the first swarm of a run its
    kernels' loading, and on a fresh install their compiling (seconds). Numba keeps a version
    per argument type, layout and writeable flag; tests/test_study_executors.py checks that no
    solve of a study loads another."""
    n, p = 5, 2
    x = np.linspace(0.0, 1.0, n * p).reshape(n, p) ** 2  # distinct particles
    even = np.linspace(0.0, 1.0, 3)
    even.setflags(write=False)
    box_step(2.0 * np.eye(p), np.ones(p), -np.ones(p), np.full(p, 0.1), 1e-10)
    candidates, _ = pso_candidates(x, np.zeros((n, p)), x.copy(), x.copy()[0],
                                   np.full((2, n, p), 0.5), 0.5, np.ones(2), np.ones(p),
                                   np.full(p, -2.0), np.full(p, 2.0), even, 1e-12)
    keep_best(candidates, np.arange(len(candidates), dtype=np.float64),
              np.argsort(np.zeros(len(candidates)), kind="stable")[:n], x.copy(), x.copy(),
              np.full(n, np.inf))
    curve_points(np.linspace(0.0, 1.0, n), x.copy(), even)
