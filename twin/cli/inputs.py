"""What INPUT and the rig flags of `twin calibrate` and `twin identify` resolve to.

INPUT is a measurement CSV or a capture.toml; the flags say how the data were measured (ports,
attachment, known distances) and win over the capture's tables.
"""

from __future__ import annotations

import argparse
import warnings
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

from twin.cli.arguments import ALL_PORTS, AUTO_ERRORS, AUTO_SIGMA, robot_from_flags
from twin.errors import InputError, UnknownChoiceError

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from twin.calibration.accuracy import TruthErrors
    from twin.calibration.result import CalibrationResult, SplitProblem
    from twin.dataset import Measurements
    from twin.io.capture_file import CalibrationSettings
    from twin.rig import Rig
    from twin.robot import RobotModel



class Inputs(NamedTuple):
    """What INPUT and the flags resolve to."""

    robot: RobotModel
    rig: Rig
    """The rig as told: ports (with those to estimate), attachment, known distances."""
    measurements_path: Path
    truth_path: Path | None
    calibration: CalibrationSettings
    """What to estimate and how; its noise the instrument's and the robot's repeatability
    (:func:`twin.analysis.misfit.reading_sigma`)."""
    flags: frozenset[str] = frozenset()
    """The rig, loss and limit flags given (``--port``, ``--distance``, ``--attachment``,
    ``--loss-scale``, ``--bounds``, ``--prior``, ``--fix``): checked against the data once they
    are read."""
    distance_source: str = "--distance"
    """Where the known distances come from: the flag, or the capture file."""
    settings_source: str = ""
    """The capture file whose ``[calibration]`` table the settings start from, if any."""

    @property
    def port_m(self) -> NDArray[np.float64] | None:
        """The first port, shape (3,), m; None without one."""
        return self.rig.ports_m[0] if len(self.rig.ports_m) else None


def _flag_rig(args: argparse.Namespace, base: Rig) -> Rig:
    """The rig of the capture (or none) with the flags' ports, attachment and distances."""
    import numpy as np

    from twin.io.capture_file import (
        parse_angles,
        parse_distances,
        parse_port_mm,
        parse_told_port,
    )

    rig = base
    ports = getattr(args, "port", None)
    if ports:
        parsed = [parse_told_port(value, "--port", "") for value in ports]
        named = [name for name, _ in parsed if name is not None]
        if len(named) != len(parsed) and len(parsed) > 1:
            raise InputError(f"{len(parsed)} ports, {len(parsed) - len(named)} without a name",
                             "one X,Y,Z, or NAME=X,Y,Z for every port", source="--port")
        if len(set(named)) != len(named):
            raise InputError("a port name twice", "distinct NAME=X,Y,Z", source="--port")
        names = tuple(named) if named else ("port",)
        rig = replace(rig, ports_m=np.stack([np.zeros(3) if port is None else port
                                             for _, port in parsed]),
                      port_names=names, estimated_ports=(),
                      unknown_ports=tuple(name for name, (_, port) in zip(names, parsed,
                                                                           strict=True)
                                          if port is None))
    if getattr(args, "attachment", None) is not None:
        rig = replace(rig, attachment_m=parse_port_mm(args.attachment, "--attachment", ""))
    if getattr(args, "distance", None):
        rig = replace(rig, distances=parse_distances(args.distance, "--distance"))
    if getattr(args, "angle", None):
        rig = replace(rig, angles=parse_angles(args.angle, "--angle"))
    estimated = [name for name in (getattr(args, "estimate_port", None) or [])
                 if name != ALL_PORTS]
    for name in estimated:
        if name not in rig.port_names:
            raise UnknownChoiceError("port", name, rig.port_names, source="--estimate-port")
    return replace(rig, estimated_ports=tuple(dict.fromkeys(estimated)))


JOINT_FLAGS = "--joint-resolution-deg or --joint-sigma-deg"
"""The flags of the joints' noise, named together by an error in it."""
FLAGS = {"errors": "--errors", "estimate": "--estimate-port", "sigma_m": "--sigma",
         "sigma_rad": "--sigma-deg",
         "loss": "--loss", "loss_scale_m": "--loss-scale", "stop": "--stop",
         "max_iterations": "--max-iterations", "train_fraction": "--train-fraction",
         "bounds": "--bounds", "priors": "--prior", "fix": "--fix",
         "joint_sigma_rad": JOINT_FLAGS}
"""The flag that sets each calibration setting, named by an error in it."""


def _joint_flags(args: argparse.Namespace, base: CalibrationSettings) -> tuple[float, ...]:
    """The joints' noise ``--joint-sigma-deg`` and ``--joint-resolution-deg`` state, rad; the
    capture's without them."""
    from twin.calibration.settings import joint_noise
    from twin.units import deg_to_rad

    sigma, resolution = (getattr(args, name, None) for name in ("joint_sigma_deg",
                                                                "joint_resolution_deg"))
    if sigma is None and resolution is None:
        return base.joint_sigma_rad
    return joint_noise(deg_to_rad(sigma or ()).tolist(), deg_to_rad(resolution or ()).tolist())


def settings_from_flags(args: argparse.Namespace, base: CalibrationSettings,
                        instrument_sigma_m: float, repeatability_m: float
                        ) -> CalibrationSettings:
    """``base`` (a capture's ``[calibration]``, or the defaults) with what the flags set; the
    noise of a reading from ``--sigma`` and ``--repeatability`` or, where absent, the given
    instrument noise and repeatability (m).

    Raises:
        InputError: naming the flag of a setting that is wrong.
    """
    from twin.analysis.misfit import reading_sigma
    from twin.units import deg_to_rad, mm_to_m

    flagged = {"estimate_port": "port", "estimate_offset": "offset",
               "estimate_scale": "scale", "estimate_attachment": "attachment",
               "estimate_base": "base", "estimate_tool": "tool"}
    estimate = {*base.estimate, *(name for flag, name in flagged.items()
                                  if getattr(args, flag, None))}
    errors = getattr(args, "errors", None)
    sigma, repeatability = getattr(args, "sigma", None), getattr(args, "repeatability", None)
    auto = sigma == AUTO_SIGMA
    scale = getattr(args, "loss_scale", None)
    changes = {
        "errors": base.errors if errors in (None, (AUTO_ERRORS,)) else errors,
        "estimate": tuple(estimate),
        "sigma_m": reading_sigma(float(mm_to_m(sigma)) if sigma and not auto
                                 else instrument_sigma_m, repeatability_m
                                 if repeatability is None else float(mm_to_m(repeatability))),
        "sigma_auto": auto or base.sigma_auto,
        "joint_sigma_rad": _joint_flags(args, base),
        "loss_scale_m": base.loss_scale_m if scale is None else float(mm_to_m(scale)),
        "sigma_rad": base.sigma_rad if getattr(args, "sigma_deg", None) is None
        else float(deg_to_rad(args.sigma_deg)),
        **{key: getattr(args, flag) for key, flag in (
            ("loss", "loss"), ("stop", "stop"), ("max_iterations", "max_iterations"),
            ("train_fraction", "train_fraction")) if getattr(args, flag, None) is not None},
        # A flag's rules come after the capture's: applied later, they win.
        **{key: (*getattr(base, key), *(rule for given in getattr(args, flag) for rule in given))
           for key, flag in (("bounds", "bounds"), ("priors", "prior"), ("fix", "fix"))
           if getattr(args, flag, None)},
    }
    try:
        return replace(base, **changes)
    except InputError as exc:
        raise exc.at(FLAGS.get(str(exc.where), "--errors"), where="") from None


def resolve_inputs(args: argparse.Namespace) -> Inputs:
    """The robot, rig, files and calibration settings named by a capture.toml or a CSV and
    the flags; flags win over the capture's tables.

    Raises:
        InputError: if a file or flag is wrong (cable lengths without a port are refused when
            the data are read).
    """
    from twin.io.capture_file import CalibrationSettings, load_capture
    from twin.problem import DEFAULT_SIGMA_M
    from twin.rig import Rig

    input_path = args.input
    flag_robot = robot_from_flags(args)  # the IRB 120 without --robot
    tension = getattr(args, "cable_tension", None)
    flags = frozenset(flag for flag, name in (("--port", "port"), ("--distance", "distance"),
                                              ("--angle", "angle"),
                                              ("--sigma-deg", "sigma_deg"),
                                              ("--attachment", "attachment"),
                                              ("--loss-scale", "loss_scale"),
                                              ("--bounds", "bounds"), ("--prior", "prior"),
                                              ("--fix", "fix"),
                                              (JOINT_FLAGS, "joint_sigma_deg"),
                                              (JOINT_FLAGS, "joint_resolution_deg"))
                      if getattr(args, name, None) is not None)
    if input_path.suffix == ".toml":
        capture = load_capture(input_path)
        rig = _flag_rig(args, capture.rig)
        return Inputs(
            robot=capture.robot if args.robot is None else flag_robot,
            rig=rig if tension is None else replace(rig, tension_n=tension),
            measurements_path=capture.measurements,
            truth_path=capture.truth,
            calibration=settings_from_flags(args, capture.calibration,
                                            capture.instrument_sigma_m,
                                            capture.repeatability_m),
            flags=flags,
            distance_source="--distance" if "--distance" in flags else str(input_path),
            settings_source=str(input_path),
        )
    return Inputs(
        robot=flag_robot,
        rig=replace(_flag_rig(args, Rig()), tension_n=tension or 0.0),
        measurements_path=input_path,
        truth_path=None,
        calibration=settings_from_flags(args, CalibrationSettings(), DEFAULT_SIGMA_M, 0.0),
        flags=flags,
    )


def truth_of(inputs: Inputs, result: CalibrationResult) -> tuple[
        NDArray[np.float64] | None, TruthErrors | None]:
    """The true D-H errors and the errors against the truth over the workspace, when the
    capture has a truth file and the model is the D-H table alone (joint-level errors are
    held to the twin's physical flange in studies, docs/studies.md)."""
    from twin.calibration.accuracy import workspace_truth_errors
    from twin.io.truth import load_truth_attachment, load_truth_delta

    path = inputs.truth_path
    if path is None or not path.exists() or inputs.calibration.errors != ("dh",):
        return None, None
    robot = inputs.robot
    delta = load_truth_delta(path, robot.n_joints, robot.is_length)
    return delta, workspace_truth_errors(result, robot.perturbed(delta),
                                         load_truth_attachment(path))


def _warn_rig_unit(inputs: Inputs, measurements: Measurements) -> None:
    """A one-line hint when the rig or the readings look given in metres (the Python API's
    unit) while the flags and files take millimetres
    (:meth:`twin.kinds.base.Kind.unit_hint`), naming the flag or the file."""
    from twin.io.measurements import UnitWarning
    from twin.kinds import KINDS

    hint = KINDS.lookup(measurements.kind).unit_hint(inputs.rig, measurements)
    if hint is not None:
        where = "--port" if inputs.truth_path is None and not hint.readings \
            else str(inputs.measurements_path)
        warnings.warn(f"{where}: {hint.text}", UnitWarning, stacklevel=2)


def prepare_error(inputs: Inputs, exc: InputError) -> InputError:
    """A mistake found while making the problem, as made in the flag or file it comes from (the
    measurement file when nothing else is named)."""
    if exc.source is not None:
        return exc
    if exc.where == "distances":
        return exc.at(inputs.distance_source, where="")
    if exc.where == "angles":
        return exc.at("--angle" if "--angle" in inputs.flags or not inputs.settings_source
                      else inputs.settings_source, where="")
    if exc.where in MODEL_FLAGS:
        flag = MODEL_FLAGS[str(exc.where)]
        return exc.at(flag, where="") if flag in inputs.flags or not inputs.settings_source \
            else exc.at(inputs.settings_source, where=f"calibration.{exc.where}")
    return InputError(exc.found, exc.expected, source=inputs.measurements_path)


def make_split(inputs: Inputs, measurements: Measurements, seed: int,
               validation: Validation | None = None) -> SplitProblem:
    """The problem of the resolved inputs (validated on a separate file when given), its
    errors naming the flag or file they come from."""
    from twin.calibration.setup import make_problem

    refuse_inapplicable(inputs, measurements)
    _warn_rig_unit(inputs, measurements)
    try:
        split = make_problem(inputs.robot, measurements, rig=inputs.rig,
                             settings=inputs.calibration, seed=seed,
                             validation=None if validation is None else validation.measurements)
    except InputError as exc:
        if exc.where == "validation" and validation is not None:
            raise exc.at(validation.path, where="") from None
        raise prepare_error(inputs, exc) from None
    return split if validation is None else split._replace(held_out=str(validation.path))


class Validation(NamedTuple):
    """A separate file to validate on (``--validate``)."""

    path: Path
    measurements: Measurements


MODEL_FLAGS = {"bounds": "--bounds", "priors": "--prior", "fix": "--fix",
               "joint_sigma_rad": JOINT_FLAGS}
"""The flag of each setting checked only against the model (what may move, the joints' noise
per joint), named by an error in it."""


def refuse_inapplicable(inputs: Inputs, measurements: Measurements) -> None:
    """Refuse a flag the data cannot use, in one line naming the flag and why, rather than
    ignore it: a port for tracker positions, a distance for cable lengths, a loss scale without
    a robust loss."""
    from twin.kinds import KINDS

    applies: dict[str, dict[str, str]] = {}
    for kind in KINDS.values():
        for flag, what in kind.flags:
            applies.setdefault(flag, {})[kind.name] = what
    for flag, kinds in applies.items():
        if flag in inputs.flags and measurements.kind not in kinds:
            raise InputError(f"{flag} with {measurements.kind} measurements",
                             f"{flag} only with " + " or ".join(kinds.values()), source=flag)
    if "--loss-scale" in inputs.flags and inputs.calibration.loss == "linear":
        raise InputError("--loss-scale with the linear loss", "it beside a robust --loss "
                         "(huber, soft_l1, cauchy): least squares has no scale",
                         source="--loss-scale")


