"""The noise of a reading when nobody states it (``--sigma auto``): from repeat readings, else
from the residuals of a first fit — and said so.

- **Repeat readings.** Rows with the same joint angles (and port or fixed point) should read
  the same: their pooled spread is the noise of a reading, measured without any model
  (:func:`twin.analysis.misfit.repeat_sigma`). When the data hold repeats, this is σ.
- **Residuals.** Otherwise a first fit (Levenberg–Marquardt on the same problem) leaves
  residuals r_i; σ is the value for which they are as large as the stated model of each row's
  variance allows: Σ r_i² / (σ² + v_i) = m − L, with v_i the joints' share of row i's variance
  (errors in variables, :meth:`twin.problem.Problem.row_sigma`; 0 without) and L the rank at
  the start, as the fit's own noise estimate counts it —
  σ̂² = Σ r² / (m − L) when the joints are exact. Such a σ explains the residuals by
  construction: the misfit test, which asks whether the residuals exceed the noise, cannot fire
  and is not made; the model's own shortcomings are then counted as noise.

A joint noise that already explains more than the residuals leaves σ at :data:`FLOOR_M`.
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np

from twin.analysis.identifiability import measurement_identifiability
from twin.analysis.misfit import repeat_sigma
from twin.calibration.settings import CalibrationSettings
from twin.problem import Problem
from twin.report.display import SIGNIFICANT, mm
from twin.solvers import get_solver
from twin.stopping import Budget

FLOOR_M = 1e-9
"""The smallest σ an estimate returns, m (a nanometre: below any instrument)."""


class NoiseEstimate(NamedTuple):
    """A σ the data gave, and how."""

    sigma_m: float
    """The noise 1σ of a reading, m."""
    source: str
    """``repeat readings, 12 degrees of freedom`` or ``the residuals of a first fit``."""

    @property
    def from_residuals(self) -> bool:
        """Whether σ was fitted to the residuals (then no misfit test)."""
        return self.source.startswith("the residuals")

    def describe(self) -> str:
        """``σ estimated from repeat readings (12 degrees of freedom): 0.0103 mm``."""
        return (f"σ estimated from {self.source}: {mm(self.sigma_m, significant=SIGNIFICANT)}"
                + ("; the misfit test, whose reference it is, is not made"
                   if self.from_residuals else ""))


def _from_residuals(residuals: np.ndarray, joints: np.ndarray, dof: int) -> float:
    """σ with Σ r² / (σ² + v) = dof (module docstring), m."""
    squares = residuals**2

    def excess(variance: float) -> float:
        return float(np.sum(squares / (variance + joints))) - dof

    if not np.any(joints > 0):
        return float(np.sqrt(np.sum(squares) / dof))
    if excess(FLOOR_M**2) <= 0:
        return FLOOR_M
    upper = float(np.sum(squares) / dof) + float(np.max(joints))
    from scipy.optimize import brentq  # 0.15 s to import: only for a σ fitted to residuals

    return float(np.sqrt(brentq(excess, FLOOR_M**2, upper, xtol=1e-30, rtol=1e-10)))


def estimate_noise(problem: Problem, budget: Budget) -> NoiseEstimate:
    """σ of a reading from the training poses (module docstring); ``budget`` stops the first
    fit."""
    rows = problem.model.kind.rows_per_pose
    at_start = problem.model.residuals(problem.x0, problem.train)
    repeats = repeat_sigma(problem.train, at_start, rows)
    if repeats is not None:
        return NoiseEstimate(max(repeats[0], FLOOR_M),
                             f"repeat readings ({repeats[1]} degrees of freedom)")
    first = get_solver("lm").solve(problem, budget, np.random.default_rng(0))
    residuals = problem.model.residuals(first.x, problem.train)
    rank = measurement_identifiability(problem.model, problem.x0, problem.train).rank
    joints = problem.row_sigma(problem.train) ** 2 - problem.sigma_m**2
    sigma = _from_residuals(residuals, np.maximum(joints, 0.0), max(residuals.size - rank, 1))
    return NoiseEstimate(sigma, "the residuals of a first fit (lm)")


def with_noise(problem: Problem, settings: CalibrationSettings
               ) -> tuple[Problem, CalibrationSettings, NoiseEstimate]:
    """The problem and settings with σ estimated (module docstring): the noise every row is
    scaled to, the filters' R and the robust loss's default scale follow it."""
    estimate = estimate_noise(problem, settings.budget)
    settings = replace(settings, sigma_m=estimate.sigma_m, sigma_auto=False)
    return (replace(problem, sigma_m=estimate.sigma_m, loss=settings.loss_function), settings,
            estimate)


__all__ = ["FLOOR_M", "NoiseEstimate", "estimate_noise", "with_noise"]
