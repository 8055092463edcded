"""Does the calibrated model fit the data? A chi-square test of the training residuals against
the noise the data imply.

After a fit, the training residuals of a model that can explain the data are the measurement
noise: with N residual rows, rank L and noise σ, ``T = Σ r² / σ²`` follows χ²(N − L). The fit
is called a **misfit** when T exceeds the χ² quantile of level 1 − :data:`ALPHA` (p < 0.001:
not chance) — on that test alone. (A guard "and RMSE > 2σ" used to sit beside it; it hid
mismatches worth several times the stated accuracy: a missed third-harmonic transmission error
of 60″ or an encoder scale error of 100 ppm give an RMSE of 1.2–1.8 σ and a flange 2–4× worse
than predicted.) A misfit has two readings, and the report gives both with the ratio: the model
misses something, or the noise is larger than stated — by ``sqrt(T / (N − L))``, the σ the
residuals imply. The report and the result say so in one line, with the likely causes (a wrong
port or attachment, joint-level errors the robot model lacks, units); the command still
succeeds. On data the model explains, the test fires at its level, 1 in 1000.

σ is the larger of the noise stated for a reading (the instrument's rated σ with its
resolution's res²/12 folded in, ``--sigma``, and the robot's repeatability seen along one
direction, ``--repeatability``: :func:`reading_sigma`) and the noise measured by repeat
readings: rows with the same joint angles (and port or fixed point) should read the same, and
their pooled spread is measured noise no model can remove. With a robust loss the rows it
rejects are left out of the test (they are listed apart). When the recorded joint angles are
noisy too (a resolution, ``--joint-resolution-deg``), each row has its own variance, the
reading's plus the joints' through the row's Jacobian (errors in variables, method-notes §7):
the test uses those variances, as the fit weights its rows by them.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.dataset import REFERENCE, Measurements
from twin.report.display import SIGNIFICANT, mm

ALPHA = 1e-3
"""Level of the chi-square test: a misfit is reported when p < ALPHA."""
FAR = 2.0
"""A refit that brings the RMSE within this many times the noise makes its cause *likely*
(:mod:`twin.calibration.diagnosis`); not part of the test."""
REPEAT_RTOL_RAD = 1e-9
"""Joint angles closer than this (rad) count as the same pose for repeat readings."""


def reading_sigma(instrument_sigma_m: float, repeatability_m: float = 0.0) -> float:
    """The noise 1σ of one reading, m: the instrument's (resolution folded in) and the robot's
    repeatability — an RMS 3-D flange scatter r, of which a length or one tracker axis sees
    r/√3 — added in quadrature."""
    return math.hypot(instrument_sigma_m, repeatability_m / math.sqrt(3.0))


class Misfit(NamedTuple):
    """The outcome of the fit test."""

    rmse_m: float
    """RMSE of the training rows tested, m."""
    noise_m: float
    """The noise the data imply, m."""
    noise_source: str
    """Where it comes from: ``stated σ`` or ``repeat readings``."""
    statistic: float
    """T = Σ r² / σ²."""
    dof: int
    """Degrees of freedom N − L."""
    threshold: float
    """The χ²(dof) quantile of level 1 − ALPHA."""
    misfit: bool
    """Whether the test rejects the model (T above the threshold)."""

    @property
    def ratio(self) -> float:
        """RMSE / noise."""
        return self.rmse_m / self.noise_m

    @property
    def p_value(self) -> float:
        """P(χ²(dof) ≥ T): the chance of residuals at least this large if the model and the
        noise were right (scipy.stats.chi2.sf without scipy.stats); the test's verdict is
        ``p_value < ALPHA``."""
        from scipy.special import gammaincc

        return float(gammaincc(self.dof / 2.0, self.statistic / 2.0))

    @property
    def implied_sigma_m(self) -> float:
        """The noise 1σ the residuals imply, sqrt(T / dof) · σ, m: what the noise would have
        to be for the model to fit."""
        return self.noise_m * math.sqrt(self.statistic / self.dof)

    def describe(self) -> str:
        """The test in words, e.g. ``χ² 5.3e+08, 4.6e+06× its 0.999 quantile 116 (73 degrees
        of freedom); RMSE 2.3e+03× the noise (stated σ)``."""
        return (f"χ² {self.statistic:.3g}, {self.statistic / self.threshold:.3g}× its "
                f"{1 - ALPHA:g} quantile {self.threshold:.3g} ({self.dof} degrees of freedom); "
                f"RMSE {self.ratio:.3g}× the noise ({self.noise_source})")

    def readings(self) -> str:
        """The two readings of a misfit, e.g. ``either the model misses something, or the
        noise is 0.016 mm, 1.6× the stated σ (0.01 mm)``."""
        implied = self.implied_sigma_m / self.noise_m
        return (f"either the model misses something, or the noise is "
                f"{mm(self.implied_sigma_m, significant=SIGNIFICANT)}, {implied:.3g}× the "
                f"{self.noise_source} ({mm(self.noise_m, significant=SIGNIFICANT)})")


def chi2_quantile(level: float, dof: int) -> float:
    """The χ²(dof) quantile of the given level (scipy.stats.chi2.ppf without scipy.stats)."""
    # scipy.special (0.15 s to import) loads when a test runs: reading a capture or a result
    # imports this module and never computes a quantile.
    from scipy.special import gammaincinv

    return float(2.0 * gammaincinv(dof / 2.0, level))


def same_poses(data: Measurements) -> NDArray[np.intp]:
    """Which rows repeat a pose: an index per row, shape (m,), equal for rows with the same
    joint angles (within :data:`REPEAT_RTOL_RAD`) and labels (port, fixed point…)."""
    keys = np.round(data.q_rad / REPEAT_RTOL_RAD).astype(np.int64)
    for labels in data.labels.values():
        keys = np.column_stack([keys, labels.indices])
    _, group = np.unique(keys, axis=0, return_inverse=True)
    return np.asarray(np.ravel(group), dtype=np.intp)


def repeat_sigma(data: Measurements, residuals_m: ArrayLike, rows_per_pose: int
                 ) -> tuple[float, int] | None:
    """The noise measured by repeat readings: pooled standard deviation of the residuals of
    rows with the same joint angles (and labels: port, fixed point…), m, and its degrees of freedom;
    None without repeats. Rows flagged ``reference`` are left out: a reference pose is revisited
    across the capture to see drift (:mod:`twin.analysis.drift`), so its spread holds the drift
    and would pass a misfit off as noise.

    Args:
        data: The poses.
        residuals_m: Their residuals, shape (rows_per_pose · m + extra,); extra rows (known
            distances) are not poses and are left out.
        rows_per_pose: Residual rows per pose.
    """
    m = len(data)
    r = np.asarray(residuals_m, dtype=np.float64)[: rows_per_pose * m].reshape(m, rows_per_pose)
    group = same_poses(data)
    if REFERENCE in data.values:
        # A reference row repeats nothing: a group of its own.
        revisit = np.flatnonzero(data.values[REFERENCE] > 0.5)
        group[revisit] = group.max() + 1 + np.arange(revisit.size)
    counts = np.bincount(group)
    dof = int(np.sum(counts[counts > 1] - 1)) * rows_per_pose
    if dof == 0:
        return None
    means = np.stack([np.bincount(group, r[:, k]) / counts for k in range(rows_per_pose)], axis=1)
    spread = float(np.sum((r - means[group]) ** 2))
    return float(np.sqrt(spread / dof)), dof


def misfit_test(residuals_m: ArrayLike, rank: int, stated_sigma_m: float,
                repeat: tuple[float, int] | None = None,
                row_sigma_m: ArrayLike | None = None) -> Misfit:
    """Test training residuals against the noise (see the module docstring).

    Args:
        residuals_m: The training residual rows tested, shape (N,), m.
        rank: Identified combinations L.
        stated_sigma_m: The instrument's stated noise 1σ, m (> 0).
        repeat: The noise measured by repeat readings and its degrees of freedom, if any.
        row_sigma_m: Each row's own noise 1σ, shape (N,), m, when the joints' noise enters it
            (errors in variables, :meth:`twin.problem.Problem.row_sigma`): the test is then
            ``T = Σ (r_i / σ_i)²``, the variances the fit weighted its rows by, and the noise
            reported their RMS.
    """
    r = np.asarray(residuals_m, dtype=np.float64)
    sigma = np.full(r.size, stated_sigma_m) if row_sigma_m is None \
        else np.asarray(row_sigma_m, dtype=np.float64)
    noise = float(np.sqrt(np.mean(sigma**2))) if sigma.size else stated_sigma_m
    source = "stated σ" if row_sigma_m is None else \
        "stated σ with the joints' noise through each row's Jacobian"
    if repeat is not None and repeat[0] > noise:
        noise, source = repeat[0], f"repeat readings, {repeat[1]} degrees of freedom"
        sigma = np.full(r.size, noise)
    dof = max(r.size - rank, 1)
    statistic = float(np.sum((r / sigma) ** 2))
    threshold = chi2_quantile(1.0 - ALPHA, dof)
    rmse = float(np.sqrt(np.mean(r**2)))
    return Misfit(rmse, noise, source, statistic, dof, threshold, bool(statistic > threshold))
