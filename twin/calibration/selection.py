"""Choosing the error model: which of the robot's error groups the data support (``--errors auto``).

Nested candidates, each one group more than the last, cheapest first: ``dh``; ``dh +
thermal`` (a growth per length, only when the measurements' ``temperature_c`` changes by more
than :data:`TEMPERATURE_SPAN_K` and the kind takes it — a warm-up is the first thing a rigid
table misses); ``+ compliance`` (n unknowns); ``+ backlash`` (n, only when the measurements
carry the approach directions); ``+ transmission`` (4n) — all of them; and last the same with
``link_compliance`` in place of ``compliance`` (each link's weight its own coefficient,
n(n+1)/2 more unknowns: for masses known only link by link). Each is fitted on the same
training poses by the same method and compared on

- the **Bayesian information criterion** of its training residuals,
  ``BIC = m ln(RSS / m) + k ln m`` with m the training residuals and k the rank of the
  Jacobian at the nominal geometry (the combinations the poses identify; an unknown nobody sees
  adds no freedom, and the directions only a perturbed geometry lifts off zero, by 1e-4 or less
  of the largest singular value, add none in practice), and
- the **validation RMSE** on the held-out poses, reported beside it.

Rule: the candidate with the lowest BIC. BIC charges ln m per identified unknown — about 5–6 for
100–400 poses — so a group is kept only when it lowers the training residuals by more than
noise fitted by that many more unknowns would; unlike the validation RMSE it does not depend on
which poses were held out. The validation column shows whether the choice holds on new poses.

A candidate needs at least :data:`POSES_PER_UNKNOWN` training poses per unknown to be worth
fitting; below that the choice warns (:class:`FewPosesWarning`), and a candidate with fewer
training residuals than unknowns is not fitted at all.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import NamedTuple

import numpy as np

from twin.analysis.identifiability import measurement_identifiability, warn_rank_deficient
from twin.calibration.pipeline import calibrate
from twin.calibration.result import CalibrationResult, SplitProblem
from twin.calibration.settings import CalibrationSettings
from twin.calibration.setup import DEFAULT_SETTINGS, make_model
from twin.calibration.split import required_poses
from twin.dataset import TEMPERATURE, Measurements
from twin.report.display import plain
from twin.rig import Rig
from twin.robot import RobotModel

NESTED = ("dh", "thermal", "compliance", "backlash", "transmission")
"""The order in which candidates add groups: a warm-up first, then fewest unknowns first."""
TEMPERATURE_SPAN_K = 0.1
"""The least change of the measurements' temperature over which thermal growth is tried: over
less every growth multiplies next to nothing (held, and the candidate a copy of the one
before)."""
POSES_PER_UNKNOWN = 3
"""Readings per identified unknown below which a fit follows the noise: the choice warns."""


class FewPosesWarning(UserWarning):
    """Fewer poses than the unknowns of an error model need to be fitted reliably."""


class Candidate(NamedTuple):
    """One fitted error model of :func:`choose_errors`."""

    errors: tuple[str, ...]
    """Its error groups."""
    result: CalibrationResult
    """The calibration."""
    rank: int
    """Identified combinations at the nominal geometry (the k of BIC)."""
    bic: float
    """m ln(RSS / m) + k ln m over the m training residuals (RSS in m²)."""

    @property
    def unknowns(self) -> int:
        """Number of unknowns fitted."""
        return self.result.model.n_params


class ErrorChoice(NamedTuple):
    """Every candidate fitted, and the one chosen."""

    candidates: tuple[Candidate, ...]
    """In nesting order."""
    chosen: int
    """Index of the lowest BIC."""
    skipped: tuple[str, ...]
    """Why candidates were left out (no approach columns, too few poses)."""

    @property
    def best(self) -> Candidate:
        """The chosen candidate."""
        return self.candidates[self.chosen]


def warn_few_poses(n_train: int, rank: int, errors: Sequence[str], rows_per_pose: int = 1
                   ) -> None:
    """Warn (:class:`FewPosesWarning`) when ``n_train`` training poses of ``rows_per_pose``
    readings each (1 for a cable, 3 for a tracker position) give fewer than
    :data:`POSES_PER_UNKNOWN` readings per identified unknown (``rank``, rig unknowns
    included)."""
    needed = -(-POSES_PER_UNKNOWN * rank // rows_per_pose)
    if n_train < needed:
        readings = f" ({n_train * rows_per_pose} readings)" if rows_per_pose > 1 else ""
        warnings.warn(
            f"{n_train} training poses{readings} for {rank} identifiable unknowns "
            f"({'+'.join(errors)} and the rig's): fewer than {POSES_PER_UNKNOWN} readings per "
            f"unknown, so the fit follows the noise; measure at least {needed} (twin plan "
            f"--errors {','.join(errors)})", FewPosesWarning, stacklevel=3)


def warn_weak_data(robot: RobotModel, split: SplitProblem, errors: Sequence[str],
                   source: str | Path, seed: int) -> None:
    """Before a calibration, warn when its training poses identify fewer directions than
    well-spread poses would (:func:`twin.analysis.identifiability.warn_rank_deficient`; not for
    fixed points, where random poses reach no common point to compare with) and when they are too
    few for the unknowns they identify (:func:`warn_few_poses`, naming the error groups
    ``errors``)."""
    problem = split.problem
    if problem.model.kind.random_poses:
        warn_rank_deficient(robot, problem.model, problem.x0, problem.train, source, seed)
    rank = measurement_identifiability(problem.model, problem.x0, problem.train).rank
    warn_few_poses(len(split.train_rows), rank, errors, problem.model.kind.rows_per_pose)


def nested_errors(has_approach: bool, has_temperature: bool = False) -> list[tuple[str, ...]]:
    """The candidate error models, in nesting order (backlash only with approach directions,
    thermal only with a changing temperature), then the largest with ``link_compliance`` for
    ``compliance``."""
    left_out = {name for name, kept in (("backlash", has_approach),
                                        ("thermal", has_temperature)) if not kept}
    groups = [name for name in NESTED if name not in left_out]
    nested = [tuple(groups[: k + 1]) for k in range(len(groups))]
    split = tuple("link_compliance" if name == "compliance" else name for name in nested[-1])
    return [*nested, split]


def _warming(measurements: Measurements) -> str | None:
    """Why thermal growth is not a candidate for these measurements, or None when it is (a
    ``temperature_c`` column changing by more than :data:`TEMPERATURE_SPAN_K`)."""
    if TEMPERATURE not in measurements.values:
        return "thermal: the measurements carry no temperature_c"
    span = float(np.ptp(measurements.values[TEMPERATURE]))
    if span <= TEMPERATURE_SPAN_K:
        return f"thermal: the temperature changes by {plain(span, significant=3)} K only"
    return None


def bic(residuals_m: np.ndarray, rank: int) -> float:
    """m ln(RSS / m) + k ln m of residuals (m,), in m, with k = ``rank``."""
    m = residuals_m.size
    return float(m * np.log(float(residuals_m @ residuals_m) / m) + rank * np.log(m))


def choose_errors(
    robot: RobotModel,
    measurements: Measurements,
    rig: Rig,
    *,
    method: str = "lm",
    settings: CalibrationSettings = DEFAULT_SETTINGS,
    seed: int = 0,
    candidates: Sequence[tuple[str, ...]] | None = None,
) -> ErrorChoice:
    """Fit every nested error model on the same split and choose by BIC (module docstring).

    Takes the arguments of :func:`twin.calibration.pipeline.calibrate` (the settings' error
    groups are each candidate's); ``candidates`` replaces the nested error models.

    Raises:
        InputError: if not even the first candidate (D-H alone) can be fitted to so few
            poses.
    """
    warming = _warming(measurements)
    models = list(candidates) if candidates is not None \
        else nested_errors(measurements.approach is not None, warming is None)
    skipped = [] if candidates is not None else [
        reason for reason in ("backlash: the measurements do not carry the approach directions"
                              if measurements.approach is None else None, warming) if reason]
    train_fraction = settings.train_fraction
    n_train = round(train_fraction * len(measurements))
    fitted: list[Candidate] = []
    for errors in models:
        candidate = replace(settings, errors=errors)
        model = make_model(robot, rig, measurements.kind, candidate)
        needed = required_poses(model.n_params, train_fraction, model.kind.rows_per_pose)
        if fitted and len(measurements) < needed:
            skipped.append(f"{'+'.join(errors)}: {len(measurements)} poses, fewer than the "
                           f"{needed} its {model.n_params} unknowns need")
            continue
        # The first candidate (D-H alone) raises InputError if even it cannot be fitted.
        result = calibrate(robot, measurements, rig=rig, method=method, settings=candidate,
                           seed=seed)
        nominal = result.identifiability
        rank = nominal.rank if nominal is not None else model.n_params
        warn_few_poses(n_train, rank, errors, model.kind.rows_per_pose)
        train = measurements.subset(result.train_rows)
        # The result's model: its rig holds what the fit set up (the thermal reference).
        residuals = result.model.residuals(result.solver.x, train)
        fitted.append(Candidate(tuple(errors), result, rank, bic(residuals, rank)))
    chosen = int(np.argmin([candidate.bic for candidate in fitted]))
    return ErrorChoice(tuple(fitted), chosen, tuple(skipped))
