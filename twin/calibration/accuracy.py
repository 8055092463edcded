"""How far an identified model is from the truth: raw, and modulo what the data cannot see.

Over workspace poses, the RMS distance between the identified and the true flange centres, and
between the identified and the true measured points (an eyelet, a tracker target, a ball), each
both as it is (in the base frame the nominal robot defines) and after the unobservable motions
of :mod:`twin.analysis.gauge` that bring the identified points closest to the true ones. When the
rig pins the base frame (a measured port, no tracker frame estimated) the two agree; with an
estimated port or tracker frame the raw error measures partly the frame, and the gauge-free
one is what the Cramér–Rao bound bounds.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from twin.analysis.gauge import gauge_free_rms, unobservable_motions
from twin.analysis.uncertainty import rms_distance
from twin.analysis.workspace import WORKSPACE_POSES, within
from twin.arrays import Array
from twin.calibration.result import CalibrationResult
from twin.geometry.kinematics import point_position, turns
from twin.robot import RobotModel


class TruthErrors(NamedTuple):
    """RMS errors over the workspace poses against the truth, m."""

    flange_m: float
    """Flange centres, raw."""
    flange_gauge_free_m: float
    """Flange centres, modulo the unobservable motions of the flange."""
    point_m: float
    """Measured points, raw."""
    point_gauge_free_m: float
    """Measured points, modulo their unobservable motions."""
    motions: tuple[str, ...]
    """The unobservable motions of the flange."""
    point_motions: tuple[str, ...]
    """The unobservable motions of the measured point."""


def rigid_truth(true_robot: RobotModel, true_attachment_m: ArrayLike, q_rad: ArrayLike
                ) -> tuple[Array, Array]:
    """Where a rigid true robot puts its flange centre and the measured point at poses q:
    shapes (k, 3) each, m, base frame.

    Args:
        true_robot: The true robot (nominal plus the true table errors).
        true_attachment_m: The true measured point in the flange frame, shape (3,), m.
        q_rad: Poses, shape (k, n), rad.
    """
    # The poses' cosines and sines once for both points (a study's 500 workspace poses: 56 µs).
    angles = turns(q_rad)
    structure, table = true_robot.structure, true_robot.dh
    return (point_position(structure, table, angles),
            point_position(structure, table, angles, true_attachment_m))


def truth_errors(result: CalibrationResult, true_flange_m: ArrayLike, true_point_m: ArrayLike,
                 q_rad: ArrayLike) -> TruthErrors:
    """Compare a calibration with the truth over poses q: the whole identified model (table and
    joint-level groups) against where the true robot put its flange and the measured point.

    Args:
        result: The calibration.
        true_flange_m: The true flange centres at the poses, shape (k, 3), m: a rigid truth's
            (:func:`rigid_truth`) or the twin's physical flange, with its joint errors and sag.
        true_point_m: The true measured points at the poses, shape (k, 3), m.
        q_rad: Workspace poses, shape (k, n), rad, visited in order (the approach directions
            of backlash are those of visiting them so).
    """
    model, x = result.model, result.solver.x
    identifiability = result.identified_identifiability
    null = identifiability.null_space if identifiability is not None \
        else np.zeros((model.n_params, 0))
    true_flange = np.asarray(true_flange_m, dtype=np.float64)
    true_point = np.asarray(true_point_m, dtype=np.float64)
    # Each gauge carries the identified points at the poses, from which its motions start.
    flange = unobservable_motions(model, x, null, q_rad)
    point = flange if model.measures_flange \
        else unobservable_motions(model, x, null, q_rad, measured=True)
    return TruthErrors(
        flange_m=rms_distance(flange.points_m, true_flange),
        flange_gauge_free_m=gauge_free_rms(flange, true_flange),
        point_m=rms_distance(point.points_m, true_point),
        point_gauge_free_m=gauge_free_rms(point, true_point),
        motions=flange.names,
        point_motions=point.names,
    )


def workspace_truth_errors(result: CalibrationResult, true_robot: RobotModel,
                           true_attachment_m: ArrayLike) -> TruthErrors:
    """:func:`truth_errors` over the calibration's workspace (the joint ranges of its training
    poses, :mod:`twin.analysis.workspace`); for a result made without one, poses within the
    joint limits drawn with the calibration's seed."""
    workspace = result.workspace or within(result.robot.lower_rad, result.robot.upper_rad,
                                           WORKSPACE_POSES, np.random.default_rng(result.seed),
                                           "the joint limits")
    q_workspace = workspace.q_rad
    return truth_errors(result, *rigid_truth(true_robot, true_attachment_m, q_workspace),
                        q_workspace)
