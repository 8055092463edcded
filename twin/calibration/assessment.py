"""What a measurement set identifies, and how well (`twin identify`).

At the nominal geometry: rank, condition and the unidentifiable combinations of the unknowns,
observability indices and the Cramér–Rao bound on the flange position over the workspace the
data cover — or, when the data do not pin the flange (an estimated attachment lets it slide
under the point they measure), on the measured point's. Then a calibration with the method
`twin calibrate` runs by default (the same fit, so the same noise estimate, in both commands),
and the same at the identified geometry, with per-parameter standard deviations and a map of
the predicted flange error over joints 2 and 3.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from twin.analysis.identifiability import Identifiability, measurement_identifiability
from twin.analysis.uncertainty import cramer_rao_rms, flange_sigma
from twin.analysis.workspace import MEASURED_RANGES, Workspace, data_workspace
from twin.arrays import Array
from twin.calibration.pipeline import solve_many
from twin.calibration.result import CalibrationResult, SplitProblem
from twin.choices import DEFAULT_METHOD
from twin.dataset import Measurements
from twin.design.optimal import DesignScore, score_data
from twin.model import Model
from twin.robot import RobotModel

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
    """The calibration (its identifiability and uncertainty at the identified geometry)."""
    workspace: Workspace
    """Where the accuracy is stated: within the joint ranges of the measured poses."""
    point_bound_m: float | None
    """When the data do not pin the flange (:attr:`pinned`), the Cramér–Rao bound on the RMS
    error of the measured point over the workspace, m, nominal geometry; else None."""

    @property
    def pinned(self) -> bool:
        """Whether the data pin the flange: not with an estimated attachment, which lets the
        flange slide under the point the data measure (no flange figure is then stated)."""
        return self.point_bound_m is None


def assess(robot: RobotModel, split: SplitProblem, measurements: Measurements, *, seed: int,
           method: str = DEFAULT_METHOD) -> Assessment:
    """Identifiability at the nominal geometry, then a calibration.

    Args:
        robot: The nominal robot.
        split: The calibration problem of the measurements, split into training and validation.
        measurements: Every pose measured.
        seed: Seed of the workspace poses and of the calibration.
        method: The calibration method (:data:`twin.solvers.SOLVERS`).
    """
    model = split.problem.model
    data = model.kind.prepare(robot, model.rig, measurements, split.settings.noise)[1]
    x0 = np.zeros(model.n_params)
    workspace = data_workspace(data.q_rad, np.random.default_rng(seed), covers=MEASURED_RANGES)
    nominal = measurement_identifiability(model, x0, data)
    # The rows as measured: each its own station and temperature (a thermal growth's columns
    # are its temperature's rise: at poses of one's choosing they are zeros).
    score = score_data(model, x0, data, nominal.base_mask, split.problem.sigma_m,
                       workspace.q_rad)
    point = cramer_rao_rms(model, x0, data, split.problem.sigma_m, workspace.q_rad)[1] \
        if model.has("attachment") else None
    result = solve_many(robot, split, [method], seed=seed)[method]
    return Assessment(data, nominal, score, result, workspace, point)


def flange_error_map(model: Model, x: Array, covariance: Array, workspace: Workspace,
                     n_per_axis: int = MAP_GRID, *, measured: bool = False
                     ) -> tuple[Array, Array, Array]:
    """The predicted flange error over a grid of joints 2 and 3 within the workspace's ranges,
    the other joints at the middle of theirs (:meth:`twin.analysis.workspace.Workspace.grid`).

    Args:
        model: The calibrated model.
        x: Its unknowns, shape (p,).
        covariance: Their covariance, shape (p, p).
        workspace: The joint ranges the map spans.
        n_per_axis: Grid points per joint.
        measured: The measured point's error instead of the flange's (for data that do not
            pin the flange).

    Returns:
        ``(q2_rad, q3_rad, error_m)``: the grid's axes (a,) and (b,), rad, and the predicted
        RMS position error, shape (a, b), m.
    """
    q2, q3, q = workspace.grid(n_per_axis)
    poses = model.poses(q)
    jacobian = model.position_jacobian(x, poses) if measured \
        else model.flange_jacobian(x, poses)
    return q2, q3, flange_sigma(jacobian, covariance).reshape(q2.size, q3.size)
