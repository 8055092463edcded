"""The model and problem of a calibration: the robot's error groups and the rig's unknowns
(:func:`make_model`), the data split and the start (:func:`make_problem`), as the settings
(:class:`~twin.calibration.settings.CalibrationSettings`) say."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from twin.calibration.result import SplitProblem
from twin.calibration.settings import RIG_UNKNOWNS, CalibrationSettings
from twin.calibration.split import required_poses, split_rows
from twin.calibration.start import check_approach
from twin.dataset import Measurements
from twin.errors import InputError
from twin.kinds import DEFAULT_KIND, KINDS
from twin.model import Model
from twin.problem import Problem
from twin.rig import Rig
from twin.robot import RobotModel
from twin.unknowns import make_groups

DEFAULT_SETTINGS = CalibrationSettings()
"""The paper's calibration: the D-H errors alone, least squares, run to convergence."""


def make_model(robot: RobotModel, rig: Rig, kind: str = DEFAULT_KIND,
               settings: CalibrationSettings = DEFAULT_SETTINGS) -> Model:
    """The measurement model of a calibration: the robot's error groups and the rig's unknowns
    the settings name (a port correction applies to the rig's estimated ports, every port
    unless :attr:`twin.rig.Rig.estimated_ports` names some).

    Args:
        robot: The nominal robot.
        rig: The nominal rig.
        kind: The measurement kind (:data:`twin.kinds.KINDS`).
        settings: Which groups to identify.

    Some kinds always identify a group (fixed-point data their fixed points, group ``points``:
    :attr:`twin.kinds.base.Kind.implied`).
    """
    measured = KINDS.lookup(kind)
    names = [*settings.groups, *measured.implied]
    return Model(robot, rig, measured, make_groups(names, robot, rig))


def cable_rig(port_m: ArrayLike | None, rig: Rig | None) -> Rig:
    """The rig of a calibration given a port alone (a cable rig) or a whole rig; an empty rig
    without either."""
    if port_m is not None and rig is not None:
        raise ValueError("give either port_m or rig")
    if rig is not None:
        return rig
    return Rig.cable(np.asarray(port_m, dtype=np.float64)) if port_m is not None else Rig()


def _check_unknowns(settings: CalibrationSettings, kind: str) -> None:
    """Refuse rig unknowns the measurement kind cannot have (a port of tracker data…)."""
    groups = KINDS.lookup(kind).groups
    for name in settings.estimate:
        if name != "attachment" and name not in groups:
            raise InputError(f"{RIG_UNKNOWNS[name]} with {kind} measurements",
                             "only the unknowns they can have: " + ", ".join(
                                 flag for group, flag in RIG_UNKNOWNS.items()
                                 if group in groups or group == "attachment"))


def make_problem(
    robot: RobotModel,
    measurements: Measurements,
    port_m: ArrayLike | None = None,
    *,
    rig: Rig | None = None,
    settings: CalibrationSettings = DEFAULT_SETTINGS,
    seed: int = 0,
) -> SplitProblem:
    """The problem the solvers see, with its train/validation split.

    The measurement kind completes the rig from the data and starts it
    (:meth:`twin.kinds.base.Kind.prepare`, :meth:`~twin.kinds.base.Kind.start`): tracker data
    with the tracker frame estimated start it at a rigid fit of the nominal model's points to
    the training readings; fixed-point data start their points at the nominal model's mean
    point of each name.

    Args:
        robot: Nominal robot.
        measurements: Joint angles (rad) and what was read (lengths, tracker positions in m,
            or fixed-point names).
        port_m: Encoder port in the base frame, shape (3,), m — shorthand for
            ``rig=Rig.cable(port_m)``; cable lengths need one of the two.
        rig: The nominal rig (ports, attachment point, tracker frame, known distances).
        settings: What to estimate, the noise, the loss and the split.
        seed: Seed of the train/validation split.

    Raises:
        InputError: if there are fewer poses than the unknowns need, the measurements lack
            what a group reads (the approach directions of backlash), or an unknown is asked
            for that these measurements cannot have (a port of tracker data…).
    """
    setup = cable_rig(port_m, rig)
    _check_unknowns(settings, measurements.kind)
    setup, measurements = KINDS.lookup(measurements.kind).prepare(robot, setup, measurements)
    model = make_model(robot, setup, measurements.kind, settings)
    check_approach(model, measurements.approach)
    fraction = settings.train_fraction
    needed = required_poses(model.n_params, fraction, model.kind.rows_per_pose)
    if len(measurements) < needed:
        percent = round(100 * fraction)
        raise InputError(
            f"{len(measurements)} poses",
            f"at least {needed} for {model.n_params} unknowns with a {percent}/{100 - percent} "
            "split",
        )
    train_rows, validation_rows = split_rows(len(measurements), seed, fraction)
    train = measurements.subset(train_rows)
    model = model.kind.start(model, train)
    problem = Problem(model, train, measurements.subset(validation_rows),
                      sigma_m=settings.sigma_m, loss=settings.loss_function)
    return SplitProblem(problem, train_rows, validation_rows, settings)
