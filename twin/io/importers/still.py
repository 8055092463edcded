"""Where a robot stood still in a recording: the windows in which every joint stayed within a
tolerance for at least a minimum time, and the median of the samples in each.

Pure numpy. A sample belongs to at most one window; windows are maximal (a still period is one
window however long it lasts).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray


class StillWindow(NamedTuple):
    """One period the robot stood still."""

    start_s: float
    """Time of its first sample, s."""
    end_s: float
    """Time of its last sample, s."""
    q_rad: NDArray[np.float64]
    """The median of its joint samples, shape (n,), rad."""
    samples: int
    """How many joint samples it holds."""


def still_windows(t_s: NDArray[np.float64], q_rad: NDArray[np.float64], tol_rad: float,
                  min_s: float) -> list[StillWindow]:
    """The still windows of joint samples.

    Args:
        t_s: Sample times, shape (m,), s, increasing.
        q_rad: Joint samples, shape (m, n), rad.
        tol_rad: Largest spread (max − min) of any joint inside a window, rad.
        min_s: Shortest window, s.

    Returns:
        The windows, in time order.
    """
    t = np.asarray(t_s, dtype=np.float64)
    q = np.asarray(q_rad, dtype=np.float64)
    if t.ndim != 1 or q.ndim != 2 or len(t) != len(q):
        raise ValueError(f"t_s {t.shape}, q_rad {q.shape}: expected (m,) and (m, n)")
    if len(t) > 1 and np.any(np.diff(t) < 0):
        raise ValueError("t_s: expected increasing times")
    windows: list[StillWindow] = []
    start, m = 0, len(t)
    while start < m:
        low, high, end = q[start].copy(), q[start].copy(), start
        # Grow the window while every joint's spread stays within the tolerance.
        while end + 1 < m:
            low_next, high_next = np.minimum(low, q[end + 1]), np.maximum(high, q[end + 1])
            if np.any(high_next - low_next > tol_rad):
                break
            low, high, end = low_next, high_next, end + 1
        if t[end] - t[start] >= min_s:
            windows.append(StillWindow(float(t[start]), float(t[end]),
                                       np.median(q[start:end + 1], axis=0), end - start + 1))
            start = end + 1
        else:
            start += 1
    return windows
