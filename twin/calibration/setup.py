"""The model and problem of a calibration: the robot's error groups and the rig's unknowns
(:func:`make_model`), the data split and the start (:func:`make_problem`), as the settings
(:class:`~twin.calibration.settings.CalibrationSettings`) say."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.calibration.noise import with_noise
from twin.calibration.result import SplitProblem
from twin.calibration.settings import RIG_UNKNOWNS, CalibrationSettings
from twin.calibration.split import required_poses, split_rows
from twin.calibration.start import check_approach
from twin.dataset import TEMPERATURE, Measurements
from twin.errors import InputError
from twin.kinds import DEFAULT_KIND, KINDS
from twin.kinds.base import Noise
from twin.model import Model
from twin.problem import Problem
from twin.rig import Rig
from twin.robot import RobotModel
from twin.unknowns import make_groups
from twin.unknowns.limits import restrict

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

    Some kinds always identify a group (fixed-point data their fixed points, group ``points``;
    cable lengths of several sessions their zeros, group ``offset``:
    :meth:`twin.kinds.base.Kind.implied_by`). The settings' bounds, priors and fixed parameters
    apply to the groups (:func:`twin.unknowns.limits.restrict`).

    Raises:
        InputError: for a bound, prior or fix that names no unknown of the model or has another
            unit (``where``: ``bounds``, ``priors``, ``fix``).
    """
    measured = KINDS.lookup(kind)
    names = list(dict.fromkeys([*settings.groups, *measured.implied_by(rig)]))
    groups = restrict(make_groups(names, robot, rig), settings.bounds, settings.priors,
                      settings.fix)
    return Model(robot, rig, measured, groups)


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


def _prepared(robot: RobotModel, measurements: Measurements, setup: Rig,
              settings: CalibrationSettings) -> tuple[Measurements, Rig]:
    """The measurements and the rig as the model reads them: ports matched by name, fixed
    points started (:meth:`twin.kinds.base.Kind.prepare`)."""
    _check_unknowns(settings, measurements.kind)
    setup, measurements = KINDS.lookup(measurements.kind).prepare(robot, setup, measurements,
                                                                   settings.noise)
    if "thermal" in settings.errors:
        _check_temperature(measurements, "")
        if setup.temperature_ref_c is None:
            setup = replace(setup, temperature_ref_c=float(np.mean(measurements.value(
                TEMPERATURE))))
    return measurements, setup


def _check_temperature(data: Measurements, where: str) -> None:
    """Refuse thermal unknowns for measurements without a temperature per row."""
    if TEMPERATURE not in data.values:
        raise InputError(f"--errors thermal with measurements without a {TEMPERATURE} column",
                         f"a {TEMPERATURE} column (°C) on every row", where=where or None)


def _held_out(validation: Measurements, kind: str, model: Model, noise: Noise
              ) -> Measurements:
    """A separate file's measurements as the model reads them (validation only).

    Raises:
        InputError: for another kind of measurement, fixed points (their points are the
            training data's own unknowns) or what the model reads and the file lacks.
    """
    implied = model.kind.implied
    if validation.kind != kind or implied:
        raise InputError(f"{validation.kind} measurements to validate on",
                         f"{kind} measurements like the training data's"
                         + (f" ({model.kind.what} are validated by --cv-by: their "
                            f"{'/'.join(implied)} are the training data's unknowns)"
                            if implied else ""), where="validation")
    held_out = model.kind.prepare(model.robot, model.rig, validation, noise)[1]
    check_approach(model, held_out.approach)
    if model.has("thermal"):
        _check_temperature(held_out, "validation")
    return held_out


def _rows(model: Model, measurements: Measurements, settings: CalibrationSettings, seed: int,
          rows: tuple[NDArray[np.intp], NDArray[np.intp]] | None, every: bool
          ) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """The training and validation rows: given, every row (a separate file validates), or a
    seeded split by the settings' share.

    Raises:
        InputError: if the training rows are fewer than the unknowns need.
    """
    fraction = 1.0 if every else settings.train_fraction
    if rows is not None:
        train_rows, validation_rows = (np.sort(np.asarray(part, dtype=np.intp)) for part in rows)
        fraction = 1.0  # what the training rows need alone
    else:
        train_rows, validation_rows = split_rows(len(measurements), seed, fraction)
    needed = required_poses(model.n_params, fraction, model.kind.rows_per_pose)
    have = len(measurements) if rows is None else len(train_rows)
    if have < needed:
        share = f"with a {round(100 * fraction)}/{100 - round(100 * fraction)} split" \
            if fraction < 1 else "with every pose trained on" if rows is None \
            else "in a fold's training poses (fewer folds, or more poses)"
        raise InputError(f"{have} {'poses' if rows is None else 'training poses'}",
                         f"at least {needed} for {model.n_params} unknowns {share}")
    return train_rows, validation_rows


def make_problem(
    robot: RobotModel,
    measurements: Measurements,
    port_m: ArrayLike | None = None,
    *,
    rig: Rig | None = None,
    settings: CalibrationSettings = DEFAULT_SETTINGS,
    seed: int = 0,
    validation: Measurements | None = None,
    rows: tuple[NDArray[np.intp], NDArray[np.intp]] | None = None,
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
        validation: Measurements of a separate file to validate on; then every row of
            ``measurements`` trains.
        rows: The training and validation rows of ``measurements`` (a fold of a
            cross-validation), instead of the seeded split.

    With ``settings.sigma_auto`` σ is estimated from the training poses
    (:mod:`twin.calibration.noise`): the problem and the split's settings carry it, the split's
    ``noise`` says how it was found.

    Raises:
        InputError: if there are fewer training poses than the unknowns need, the
            measurements lack what a group reads (the approach directions of backlash), or an
            unknown is asked for that these measurements cannot have (a port of tracker
            data…).
    """
    measurements, setup = _prepared(robot, measurements, cable_rig(port_m, rig), settings)
    model = make_model(robot, setup, measurements.kind, settings)
    check_approach(model, measurements.approach)
    held_out = None if validation is None else _held_out(validation, measurements.kind, model,
                                                           settings.noise)
    train_rows, validation_rows = _rows(model, measurements, settings, seed, rows,
                                        held_out is not None)
    train = measurements.subset(train_rows)
    model = model.kind.start(model, train)
    # An angle's noise: a prismatic joint's recorded travel counts as exact (a linear axis's
    # encoder resolves micrometres).
    joints = np.where(robot.prismatic, 0.0, settings.joint_sigma(robot.n_joints))
    problem = Problem(model, train, measurements.subset(validation_rows) if held_out is None
                      else held_out, sigma_m=settings.sigma_m, loss=settings.loss_function,
                      joint_sigma_rad=joints)
    noise = None
    if settings.sigma_auto:
        problem, settings, noise = with_noise(problem, settings)
    return SplitProblem(problem, train_rows, validation_rows, settings,
                        held_out="" if held_out is None else "a separate file", noise=noise)
