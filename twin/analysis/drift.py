"""Does the rig drift during a capture? A test of the reference pose's readings against time.

A capture may revisit a reference pose (rows flagged ``reference``, :data:`twin.dataset.REFERENCE`)
— the same joint angles, so the same reading, but for the noise, unless something changed in
between: the arm warming up, the encoder's cable creeping, the instrument's stand settling.
Each reference pose's readings are regressed on time (``t_s``, else the row order) by least
squares, each of the kind's reading rows apart (one for a length, three for a position): a
slope b over times with spread ``S_tt = Σ (t − t̄)²`` has the standard error σ / sqrt(S_tt), and
``z = b · sqrt(S_tt) / σ`` is N(0, 1) when nothing drifts. The capture is said to **drift** when
the largest |z| of the k slopes tested exceeds the two-sided quantile of level
:data:`~twin.analysis.misfit.ALPHA` / k (Bonferroni: p < 0.001 over them all, the level of the
misfit test).

σ is the larger of the noise stated for a reading and the pooled scatter of the reference
readings about their lines (a noise larger than stated shows there, and the test then asks
whether the drift exceeds that noise; a curved drift's bend counts as noise, which makes the
test conservative).

The readings are taken from the kind's residual rows at one fixed set of unknowns: at one pose
the model's reading is one number, so a reading's change is its residual's, with the opposite
sign. Kinds whose readings are the joint angles themselves (a fixed point, a plane) read
nothing at a revisited pose: their series are flat.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.analysis.misfit import ALPHA, same_poses
from twin.arrays import Array
from twin.dataset import REFERENCE, TIME, Measurements

MIN_READINGS = 3
"""Readings of a reference pose the test needs: a line through two fits them exactly."""


class Series(NamedTuple):
    """One reference pose's readings against time."""

    rows: NDArray[np.intp]
    """Its rows among the measurements, in time order, shape (k,)."""
    time_s: Array
    """Each reading's time, shape (k,), s (or the row's index without ``t_s``)."""
    reading_m: Array
    """Each reading less the series' mean, shape (k, c), m (c reading rows per pose)."""
    slope_m_per_s: Array
    """The fitted slope of each reading row, shape (c,), m/s (m per row without ``t_s``)."""
    z: Array
    """Each slope over its standard error, shape (c,)."""

    @property
    def drift_m(self) -> Array:
        """How far each reading row moved over the series' time span (slope · span), (c,), m."""
        return np.asarray(self.slope_m_per_s * np.ptp(self.time_s), dtype=np.float64)

    @property
    def spread_m(self) -> float:
        """The readings' standard deviation about their mean, over the reading rows, m."""
        k, c = self.reading_m.shape
        return float(np.sqrt(np.sum(self.reading_m**2) / max((k - 1) * c, 1)))


class Drift(NamedTuple):
    """The outcome of the drift test."""

    series: tuple[Series, ...]
    """Each reference pose read at least :data:`MIN_READINGS` times."""
    timed: bool
    """Whether the times are the rows' ``t_s`` (else their order)."""
    noise_m: float
    """The noise 1σ of one reading the test used, m."""
    noise_source: str
    """Where it comes from: ``stated σ`` or the scatter about the lines."""
    statistic: float
    """The largest |z| of the slopes tested."""
    threshold: float
    """The two-sided N(0, 1) quantile of level ALPHA / tests."""
    tests: int
    """Slopes tested (series × reading rows)."""
    references: int
    """Rows flagged reference, tested or not."""

    @property
    def drift(self) -> bool:
        """Whether the readings drift beyond the noise (the largest |z| above the threshold)."""
        return self.tests > 0 and self.statistic > self.threshold

    @property
    def time_unit(self) -> str:
        """``s``, or ``row`` when the rows carry no time."""
        return "s" if self.timed else "row"


def has_reference_rows(data: Measurements) -> bool:
    """Whether any row of ``data`` is flagged reference."""
    return REFERENCE in data.values and bool(np.any(data.values[REFERENCE] > 0.5))


def reference_drift(data: Measurements, residuals_m: ArrayLike, rows_per_pose: int,
                    stated_sigma_m: float) -> Drift | None:
    """Test the reference rows of ``data`` for drift (module docstring).

    Args:
        data: The measurements, some rows flagged reference; their order is the capture's
            when they carry no time.
        residuals_m: The kind's residual rows at one fixed x, shape (rows_per_pose · m + extra,),
            m (extra rows, known distances, are not poses and are left out).
        rows_per_pose: Residual rows per pose.
        stated_sigma_m: The noise 1σ stated for a reading, m (> 0).

    Returns:
        None when no row is flagged reference.
    """
    if not has_reference_rows(data):
        return None
    m = len(data)
    reading = -np.asarray(residuals_m, dtype=np.float64)[: rows_per_pose * m].reshape(
        m, rows_per_pose)
    timed = TIME in data.values
    time = data.values[TIME] if timed else np.arange(m, dtype=np.float64)
    flagged = np.flatnonzero(data.values[REFERENCE] > 0.5)
    pose = same_poses(data)[flagged]
    series = []
    for key in np.unique(pose):
        rows = flagged[pose == key]
        rows = rows[np.argsort(time[rows], kind="stable")]
        if rows.size >= MIN_READINGS and np.ptp(time[rows]) > 0:
            series.append(_line(rows, time[rows], reading[rows]))
    return _test(tuple(series), timed, stated_sigma_m, flagged.size)


class _Line(NamedTuple):
    series: Series
    scatter: float
    dof: int


def _line(rows: NDArray[np.intp], time_s: Array, reading_m: Array) -> _Line:
    """The least-squares line of each reading row on time, with unit-noise z (σ = 1 m: the test
    divides by σ), and the sum of squares about the lines with its degrees of freedom."""
    centred = reading_m - reading_m.mean(axis=0)
    dt = time_s - time_s.mean()
    s_tt = float(dt @ dt)
    slope = dt @ centred / s_tt
    about = centred - dt[:, None] * slope
    series = Series(rows, time_s, centred, slope, slope * math.sqrt(s_tt))
    return _Line(series, float(np.sum(about**2)), (rows.size - 2) * reading_m.shape[1])


def _test(lines: tuple[_Line, ...], timed: bool, stated_sigma_m: float, references: int
          ) -> Drift:
    """Scale the slopes' z by the noise and compare the largest with the Bonferroni quantile."""
    dof = sum(line.dof for line in lines)
    scatter = math.sqrt(sum(line.scatter for line in lines) / dof) if dof else 0.0
    noise, source = stated_sigma_m, "stated σ"
    if scatter > noise:
        noise, source = scatter, f"the scatter about the lines, {dof} degrees of freedom"
    series = tuple(line.series._replace(z=line.series.z / noise) for line in lines)
    tests = sum(s.z.size for s in series)
    statistic = max((float(np.max(np.abs(s.z))) for s in series), default=0.0)
    from scipy.special import ndtri

    threshold = float(-ndtri(ALPHA / (2 * tests))) if tests else math.inf
    return Drift(series, timed, noise, source, statistic, threshold, tests, references)
