"""What a measurement set identifies, and how well (`twin identify`).

At the nominal geometry: rank, condition and the unidentifiable combinations of the unknowns,
observability indices and the Cramér–Rao bound on the flange position over the workspace. Then
an ``lm-base`` calibration, and the same at the identified geometry, with per-parameter standard
deviations and a map of the predicted flange error over joints 2 and 3.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from twin.analysis.identifiability import Identifiability, measurement_identifiability
from twin.analysis.uncertainty import flange_sigma
from twin.analysis.workspace import MEASURED_RANGES, Workspace, data_workspace
from twin.arrays import Array
from twin.calibration.pipeline import solve_many
from twin.calibration.result import CalibrationResult, SplitProblem
from twin.dataset import Measurements
from twin.design.optimal import DesignScore, score_poses
from twin.model import Model
from twin.robot import RobotModel

METHOD = "lm-base"
"""The calibration an assessment runs: LM on the base parameters, with their uncertainty."""
MAP_GRID = 41
"""Grid points per axis of the accuracy map over joints 2 and 3."""


class Assessment(NamedTuple):
    """What a measurement set identifies (:func:`assess`)."""

    data: Measurements
    """The measurements, their labels matched to the model's rig (its ports by name)."""
    nominal: Identifiability
    """Identifiability at the nominal geometry, all poses."""
    score: DesignScore
    """Observability and the Cramér–Rao flange RMS over the workspace, nominal geometry."""
    result: CalibrationResult
    """The lm-base calibration (its identifiability and uncertainty at the identified
    geometry)."""
    workspace: Workspace
    """Where the accuracy is stated: within the joint ranges of the measured poses."""


def assess(robot: RobotModel, split: SplitProblem, measurements: Measurements, *, seed: int
           ) -> Assessment:
    """Identifiability at the nominal geometry, then an lm-base calibration.

    Args:
        robot: The nominal robot.
        split: The calibration problem of the measurements, split into training and validation.
        measurements: Every pose measured.
        seed: Seed of the workspace poses and of the calibration.
    """
    model = split.problem.model
    data = model.kind.prepare(robot, model.rig, measurements, split.settings.noise)[1]
    x0 = np.zeros(model.n_params)
    workspace = data_workspace(data.q_rad, np.random.default_rng(seed), covers=MEASURED_RANGES)
    nominal = measurement_identifiability(model, x0, data)
    score = score_poses(model, x0, data.q_rad, nominal.base_mask, split.problem.sigma_m,
                        workspace.q_rad)
    result = solve_many(robot, split, [METHOD], seed=seed)[METHOD]
    return Assessment(data, nominal, score, result, workspace)


def flange_error_map(model: Model, x: Array, covariance: Array, workspace: Workspace,
                     n_per_axis: int = MAP_GRID) -> tuple[Array, Array, Array]:
    """The predicted flange error over a grid of joints 2 and 3 within the workspace's ranges,
    the other joints at the middle of theirs (:meth:`twin.analysis.workspace.Workspace.grid`).

    Args:
        model: The calibrated model.
        x: Its unknowns, shape (p,).
        covariance: Their covariance, shape (p, p).
        workspace: The joint ranges the map spans.
        n_per_axis: Grid points per joint.

    Returns:
        ``(q2_rad, q3_rad, error_m)``: the grid's axes (a,) and (b,), rad, and the predicted
        RMS flange position error, shape (a, b), m.
    """
    q2, q3, q = workspace.grid(n_per_axis)
    jacobian = model.flange_jacobian(x, model.poses(q))
    return q2, q3, flange_sigma(jacobian, covariance).reshape(q2.size, q3.size)
