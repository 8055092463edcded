"""Cross-validation: every pose held out once, the model fitted on the others.

A train/validation split scores a model on a fifth of the data and loses it for the fit. Real
data sets are small; papers on real robots report held-out figures over folds instead:

- **k-fold**: the poses in a seeded random order cut into k folds of (nearly) equal size; each
  fold held out in turn, the model fitted on the other k − 1;
- **leave one group out**: the poses grouped by a label (a fixture placement, a session, a
  day): each group held out in turn — what the model is worth where it was not trained, the
  honest figure when poses within a group resemble each other.

Each fold is a full calibration (:func:`twin.calibration.pipeline.solve_many`: same settings,
same method, unseen directions held) scored on its held-out poses as any validation is
(:mod:`twin.calibration.held_out`: rig unknowns only the held-out poses touch fitted to
them). Reported: each fold's held-out metrics, their mean, RMS and spread over the folds, and
the pooled metrics of every held-out row together (each row scored exactly once). The model to
use is then fitted on every pose (``train_fraction = 1``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.analysis.metrics import Metrics, metrics
from twin.calibration.held_out import held_out_residuals
from twin.calibration.pipeline import solve_many
from twin.calibration.settings import CalibrationSettings
from twin.calibration.setup import DEFAULT_SETTINGS, make_problem
from twin.choices import MAX_FOLDS, MIN_FOLDS
from twin.dataset import Measurements
from twin.errors import InputError
from twin.rig import Rig
from twin.robot import RobotModel
from twin.solvers import get_solver


class Fold(NamedTuple):
    """One fold: what was held out and how the model fitted without it did there."""

    label: str
    """The fold's name: ``fold 3`` or the group's label."""
    rows: NDArray[np.intp]
    """The held-out rows of the measurements, ascending."""
    before: Metrics
    """The nominal model on the held-out rows, m."""
    held_out: Metrics
    """The calibrated model on the held-out rows, m."""
    train: Metrics
    """The calibrated model on its training rows, m."""
    residuals_m: NDArray[np.float64]
    """The held-out rows' residuals, shape (M,), m."""
    before_m: NDArray[np.float64]
    """The nominal model's residuals on the same rows, shape (M,), m."""


class CrossValidation(NamedTuple):
    """Every fold, and the figures over them."""

    method: str
    how: str
    """``5 random folds (seed 0)`` or ``leave one placement out``."""
    folds: tuple[Fold, ...]

    @property
    def pooled(self) -> Metrics:
        """The metrics of every held-out row together (each scored once), m."""
        return metrics(np.concatenate([fold.residuals_m for fold in self.folds]))

    @property
    def pooled_before(self) -> Metrics:
        """The nominal model's metrics over the same rows, m."""
        return metrics(np.concatenate([fold.before_m for fold in self.folds]))

    def rmse_over_folds(self) -> tuple[float, float, float]:
        """The held-out RMSE of the folds: mean, RMS and standard deviation, m."""
        values = np.array([fold.held_out.rmse for fold in self.folds])
        return float(np.mean(values)), float(np.sqrt(np.mean(values**2))), float(np.std(values))


def random_folds(n_rows: int, folds: int, seed: int) -> list[tuple[str, NDArray[np.intp]]]:
    """``folds`` folds of ``n_rows`` rows in a seeded random order, (label, rows) each.

    Raises:
        InputError: for fewer than two folds or more folds than rows.
    """
    if not MIN_FOLDS <= folds <= min(n_rows, MAX_FOLDS):
        raise InputError(f"{folds} folds of {n_rows} poses", f"from {MIN_FOLDS} to "
                         f"{min(n_rows, MAX_FOLDS)} folds", where="cv")
    order = np.random.default_rng(seed).permutation(n_rows)
    return [(f"fold {k + 1}", np.sort(part)) for k, part in
            enumerate(np.array_split(order, folds))]


def group_folds(labels: Sequence[str]) -> list[tuple[str, NDArray[np.intp]]]:
    """One fold per distinct label, in the order they first appear, (label, rows) each.

    Raises:
        InputError: for fewer than two groups.
    """
    names = list(dict.fromkeys(labels))
    if len(names) < MIN_FOLDS:
        raise InputError(f"{len(names)} group{'s' if len(names) != 1 else ''}",
                         f"at least {MIN_FOLDS} to leave one out", where="cv_by")
    array = np.asarray(labels, dtype=object)
    return [(name, np.flatnonzero(array == name)) for name in names]


def cross_validate(
    robot: RobotModel,
    measurements: Measurements,
    port_m: ArrayLike | None = None,
    *,
    rig: Rig | None = None,
    method: str = "lm",
    settings: CalibrationSettings = DEFAULT_SETTINGS,
    seed: int = 0,
    folds: int | None = None,
    groups: Sequence[str] | None = None,
    group_name: str = "group",
) -> CrossValidation:
    """Cross-validate a calibration (module docstring): k random folds, or one fold per
    group label.

    Args:
        robot, measurements, port_m, rig, method, settings, seed: As for
            :func:`twin.calibration.pipeline.calibrate` (the seed also orders the folds).
        folds: k, for k-fold cross-validation.
        groups: One label per row of the measurements, for leave-one-group-out (instead of
            ``folds``).
        group_name: What a label names (``placement``, ``session``), for the report.

    Raises:
        InputError: for neither or both of ``folds`` and ``groups``, labels not one per row, or
            a fold whose training poses are too few.
    """
    if (folds is None) == (groups is None):
        raise InputError("folds and groups" if folds else "neither folds nor groups",
                         "one of them: k random folds or a label per row", where="cv")
    if groups is not None and len(groups) != len(measurements):
        raise InputError(f"{len(groups)} labels for {len(measurements)} rows", "one per row",
                         where="cv_by")
    parts = random_folds(len(measurements), folds, seed) if folds is not None \
        else group_folds(list(groups or ()))
    name = get_solver(method).name
    everything = np.arange(len(measurements))
    done = []
    for label, held in parts:
        train = np.setdiff1d(everything, held)
        split = make_problem(robot, measurements, port_m, rig=rig, settings=settings, seed=seed,
                             rows=(train, held))
        # A fold reads its answer and training metrics, not the checks a report shows.
        result = solve_many(robot, split, [name], seed=seed, report=False)[name]
        model, train_data, held_data = (split.problem.model, split.problem.train,
                                        split.problem.validation)
        residuals = held_out_residuals(model, result.x, train_data, held_data)
        before = held_out_residuals(model, split.problem.x0, train_data, held_data)
        done.append(Fold(label, held, metrics(before), metrics(residuals),
                         result.metrics["train"], residuals, before))
    how = f"{folds} random folds (seed {seed})" if folds is not None \
        else f"leave one {group_name} out"
    return CrossValidation(name, how, tuple(done))


def final_settings(settings: CalibrationSettings) -> CalibrationSettings:
    """The settings of the model fitted after a cross-validation: every pose trained on."""
    return replace(settings, train_fraction=1.0)


__all__ = ["CrossValidation", "Fold", "cross_validate", "final_settings", "group_folds",
           "random_folds"]
