"""`twin calibrate`: identify the robot's errors from a measurement file or a capture.

``--errors`` chooses the robot's error groups (D-H by default; transmission, backlash and
compliance beside it), or ``auto`` fits nested choices and keeps the one the data support
(:mod:`twin.selection`). The rig flags say how the data were measured (docs/measurements.md).
"""

from __future__ import annotations

import argparse
import warnings
from dataclasses import replace
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from twin.accuracy import TruthErrors, truth_errors
from twin.calibration import (
    TRAIN_FRACTION,
    WORKSPACE_POSES,
    CalibrationResult,
    SplitProblem,
    make_problem,
    solve_many,
)
from twin.cli.arguments import (
    AUTO,
    add_robot_flags,
    error_groups,
    integer,
    number,
    robot_from_flags,
    seed,
    share,
    sigma_mm,
)
from twin.dataset import Measurements
from twin.diagnosis import likely_causes
from twin.errors import InputError, UnknownChoiceError
from twin.identifiability import RankWarning, measurement_identifiability, spread_rank
from twin.io.capture_file import (
    CalibrationSettings,
    load_capture,
    parse_distance,
    parse_named_port,
    parse_port_mm,
)
from twin.io.measurements import load_measurements
from twin.io.paths import InputPath, OutputFile
from twin.io.results import choice_to_dict, result_to_dict, write_json
from twin.io.truth import load_truth_attachment, load_truth_delta
from twin.loss import DEFAULT_SCALE_SIGMAS, LOSSES, Loss
from twin.problem import DEFAULT_SIGMA_M
from twin.report import format_choice, format_comparison, format_result
from twin.rig import MAX_TENSION_N, Rig
from twin.robot import RobotModel, default_robot
from twin.selection import choose_errors, warn_few_poses
from twin.solvers import SOLVERS, get_solver, solver_choices
from twin.stopping import MAX_ITERATIONS, PROTOCOLS
from twin.synthetic import random_poses
from twin.units import mm_to_m
from twin.unknowns import ERRORS
from twin.viz import add_rerun_flags, calibration_log


def add_parser(subparsers: Any) -> None:
    """Register the subcommand."""
    parser = subparsers.add_parser(
        "calibrate",
        help="identify the robot's errors from cable, tracker or fixed-point measurements",
        description="Identify the errors of a robot (and the rig's unknowns) from "
        "measurements. INPUT is a measurement CSV (q1..qN in degrees and one of: length in mm, "
        "with --port; x,y,z in mm from a laser tracker; point, the name of a fixed place) or a "
        "capture.toml written by `twin simulate` or `twin capture`. docs/measurements.md shows "
        "each rig.",
    )
    parser.add_argument("input", type=InputPath, metavar="INPUT",
                        help="MEASUREMENTS.csv (- for standard input) or capture.toml")
    add_robot_flags(parser)
    add_rig_flags(parser)
    parser.add_argument("--errors", type=error_groups(auto=True), metavar="GROUPS",
                        help="the robot's error groups to identify, comma-separated: "
                        + ", ".join(ERRORS) + " (compliance or link_compliance); or auto: "
                        "fit dh, then add compliance, backlash, transmission one at a time, "
                        "then all with link_compliance, and keep the lowest BIC (default: the "
                        "capture's, else dh)")
    parser.add_argument("--cable-tension", type=number(0.0, MAX_TENSION_N), metavar="N",
                        help="the cable's pull towards the port in newtons (the encoder's "
                        "spring force; loads the joints for the compliance group); default: "
                        "the capture's, else 0")
    parser.add_argument(
        "--method", default="lm",
        help="method name or paper alias, or 'all': " + ", ".join(solver_choices()),
    )
    parser.add_argument("--seed", type=seed, default=0,
                        help="seed of the split and of the method")
    parser.add_argument("--estimate-offset", action="store_true",
                        help="also identify an unknown cable-length offset")
    parser.add_argument("--sigma", type=sigma_mm, metavar="MM",
                        help="the instrument's noise 1σ in mm: the filters' measurement noise "
                        "and the misfit test's reference (default: the capture's [encoder] "
                        "sigma_mm with its resolution, else 0.01)")
    parser.add_argument("--loss", choices=LOSSES,
                        help="how residual rows count: linear (least squares, default) or a "
                        "robust loss that keeps a few gross errors from steering the fit; the "
                        "rows it rejects are listed (docs/measurements.md)")
    parser.add_argument("--loss-scale", type=sigma_mm, metavar="MM",
                        help=f"the robust loss's scale in mm (default {DEFAULT_SCALE_SIGMAS:g} "
                        "σ); rows beyond three scales count as rejected")
    parser.add_argument("--stop", choices=PROTOCOLS,
                        help="stopping protocol: 'converge' (default: stop on stated "
                        "convergence tests) or 'paper' (the paper's: f changes by less than "
                        "0.001 mm², 60 iterations, cascades 30 + 30); default: the capture's")
    parser.add_argument("--max-iterations", type=integer(1, MAX_ITERATIONS), metavar="N",
                        help="iteration limit of every method and cascade stage (default: the "
                        "protocol's, 200 to converge, 60 / 30 + 30 for the paper's)")
    parser.add_argument("--train-fraction", type=share, metavar="SHARE",
                        help="share of the poses used for identification (default: the "
                        "capture's, else 0.8)")
    parser.add_argument("--json", type=OutputFile, metavar="OUT.json",
                        help="write the result as JSON")
    add_rerun_flags(parser)
    parser.set_defaults(func=run)


def add_rig_flags(parser: argparse.ArgumentParser) -> None:
    """The flags that tell the rig and which of its unknowns to identify (calibrate, identify).
    """
    parser.add_argument("--port", action="append", metavar="[NAME=]X,Y,Z",
                        help="encoder port in mm, robot base frame; NAME=X,Y,Z, repeated, for "
                        "an encoder moved between ports (the CSV's port column names each "
                        "row's)")
    parser.add_argument("--estimate-port", action="append", nargs="?", const=ALL_PORTS,
                        metavar="NAME", help="also identify a correction of the ports (of the "
                        "named one, repeated for several; the others stay as measured)")
    parser.add_argument("--attachment", metavar="X,Y,Z",
                        help="the measured point (cable eyelet, tracker target, ball) in the "
                        "flange frame, mm (default 0,0,0: the flange centre)")
    parser.add_argument("--estimate-attachment", action="store_true",
                        help="also identify the measured point in the flange frame")
    parser.add_argument("--estimate-base", action="store_true",
                        help="tracker positions: also identify the tracker-to-base transform, "
                        "started at a rigid fit of the nominal model's points")
    parser.add_argument("--distance", action="append", metavar="A,B=MM",
                        help="fixed points: a known distance between the points named A and B, "
                        "mm (a ball fixture's socket spacing); repeat for several")


ALL_PORTS = ""
"""What a bare --estimate-port stands for: every port."""


class Inputs(NamedTuple):
    """What INPUT and the flags resolve to."""

    robot: RobotModel
    rig: Rig
    """The rig as told: ports (with those to estimate), attachment, known distances."""
    measurements_path: Path
    truth_path: Path | None
    calibration: CalibrationSettings
    sigma_m: float
    """The instrument's noise 1σ, m."""

    @property
    def port_m(self) -> NDArray[np.float64] | None:
        """The first port, shape (3,), m; None without one."""
        return self.rig.ports_m[0] if len(self.rig.ports_m) else None

    @property
    def loss(self) -> Loss:
        """The loss the settings ask for, its scale defaulting to 3 σ."""
        settings = self.calibration
        scale = float(mm_to_m(settings.loss_scale_mm)) if settings.loss_scale_mm is not None \
            else DEFAULT_SCALE_SIGMAS * self.sigma_m
        return Loss(settings.loss, scale)


def _flag_rig(args: argparse.Namespace, base: Rig) -> Rig:
    """The rig of the capture (or none) with the flags' ports, attachment and distances."""
    rig = base
    ports = getattr(args, "port", None)
    if ports:
        parsed = [parse_named_port(value, "--port", "") for value in ports]
        named = [name for name, _ in parsed if name is not None]
        if len(named) != len(parsed) and len(parsed) > 1:
            raise InputError(f"{len(parsed)} ports, {len(parsed) - len(named)} without a name",
                             "one X,Y,Z, or NAME=X,Y,Z for every port", source="--port")
        if len(set(named)) != len(named):
            raise InputError("a port name twice", "distinct NAME=X,Y,Z", source="--port")
        rig = replace(rig, ports_m=np.stack([port for _, port in parsed]),
                      port_names=tuple(named) if named else ("port",), estimated_ports=())
    if getattr(args, "attachment", None) is not None:
        rig = replace(rig, attachment_m=parse_port_mm(args.attachment, "--attachment", ""))
    if getattr(args, "distance", None):
        rig = replace(rig, distances=tuple(parse_distance(value, "--distance", "")
                                           for value in args.distance))
    estimated = [name for name in (getattr(args, "estimate_port", None) or [])
                 if name != ALL_PORTS]
    for name in estimated:
        if name not in rig.port_names:
            raise UnknownChoiceError("port", name, rig.port_names, source="--estimate-port")
    return replace(rig, estimated_ports=tuple(dict.fromkeys(estimated)))


def resolve_inputs(args: argparse.Namespace) -> Inputs:
    """The robot, rig, files and calibration settings named by a capture.toml or a CSV and
    the flags; flags win over the capture's tables.

    Raises:
        InputError: if a file or flag is wrong (cable lengths without a port are refused when
            the data are read).
    """
    input_path = args.input
    named = robot_from_flags(args)
    fraction = getattr(args, "train_fraction", None)
    stop, limit = getattr(args, "stop", None), getattr(args, "max_iterations", None)
    loss, scale = getattr(args, "loss", None), getattr(args, "loss_scale", None)
    flags = {"estimate_port": bool(getattr(args, "estimate_port", None)),
             "estimate_offset": getattr(args, "estimate_offset", False),
             "estimate_attachment": args.estimate_attachment,
             "estimate_base": args.estimate_base}
    sigma = getattr(args, "sigma", None)
    errors = getattr(args, "errors", None)
    errors = None if errors == (AUTO,) else errors
    tension = getattr(args, "cable_tension", None)
    if input_path.suffix == ".toml":
        capture = load_capture(input_path)
        settings = capture.calibration
        settings = replace(
            settings, **{key: value or getattr(settings, key) for key, value in flags.items()},
            train_fraction=fraction or settings.train_fraction, stop=stop or settings.stop,
            max_iterations=limit or settings.max_iterations, loss=loss or settings.loss,
            loss_scale_mm=scale or settings.loss_scale_mm, errors=errors or settings.errors,
            cable_tension_n=settings.cable_tension_n if tension is None else tension)
        return Inputs(
            robot=named if named is not None else capture.robot,
            rig=replace(_flag_rig(args, capture.rig), tension_n=settings.cable_tension_n),
            measurements_path=capture.measurements,
            truth_path=capture.truth,
            calibration=settings,
            sigma_m=float(mm_to_m(sigma)) if sigma else capture.sigma_m,
        )
    settings = CalibrationSettings(
        **flags, train_fraction=fraction or TRAIN_FRACTION, stop=stop or PROTOCOLS[0],
        max_iterations=limit, loss=loss or LOSSES[0], loss_scale_mm=scale,
        errors=errors or ("dh",), cable_tension_n=tension or 0.0)
    return Inputs(
        robot=named if named is not None else default_robot(),
        rig=replace(_flag_rig(args, Rig()), tension_n=settings.cable_tension_n),
        measurements_path=input_path,
        truth_path=None,
        calibration=settings,
        sigma_m=float(mm_to_m(sigma)) if sigma else DEFAULT_SIGMA_M,
    )


def warn_rank_deficient(robot: RobotModel, split: SplitProblem, source: Path,
                        seed: int) -> None:
    """Warn, before anything is calibrated, when the training poses identify fewer directions
    than the same unknowns on well-spread poses: the result is then arbitrary along the
    directions these poses miss (all rows alike give rank 1)."""
    problem = split.problem
    found = measurement_identifiability(problem.model, problem.x0, problem.train).rank
    reachable = spread_rank(problem.model, robot, np.random.default_rng(seed))
    if found < reachable:
        warnings.warn(
            f"{source}: the {len(problem.train)} training poses identify {found} of the "
            f"{reachable} directions well-spread poses identify ({problem.model.n_params} "
            "unknowns); the calibration below is arbitrary along the other "
            f"{reachable - found}: measure more varied poses (twin plan)",
            RankWarning, stacklevel=2)


def truth_of(inputs: Inputs, result: CalibrationResult) -> tuple[
        NDArray[np.float64] | None, TruthErrors | None]:
    """The true D-H errors and the errors against the truth over the workspace, when the
    capture has a truth file and the model is the D-H table alone (joint-level errors are
    held to the twin's physical flange in studies, docs/studies.md)."""
    path = inputs.truth_path
    if path is None or not path.exists() or inputs.calibration.errors != ("dh",):
        return None, None
    robot = inputs.robot
    delta = load_truth_delta(path, robot.n_joints, robot.is_length)
    q_workspace = random_poses(robot, WORKSPACE_POSES, np.random.default_rng(result.seed))
    return delta, truth_errors(result, robot.perturbed(delta), load_truth_attachment(path),
                               q_workspace)


def make_split(inputs: Inputs, measurements: Measurements, seed: int) -> SplitProblem:
    """The problem of the resolved inputs, its errors naming the measurement file."""
    settings = inputs.calibration
    if measurements.kind == "length" and not len(inputs.rig.ports_m):
        raise InputError("no --port", "the encoder port as --port X,Y,Z in mm (or "
                         "NAME=X,Y,Z per port, or a capture.toml as INPUT)",
                         source=inputs.measurements_path)
    try:
        return make_problem(
            inputs.robot, measurements, rig=inputs.rig, errors=settings.errors, seed=seed,
            estimate_port=settings.estimate_port, estimate_offset=settings.estimate_offset,
            estimate_attachment=settings.estimate_attachment,
            estimate_base=settings.estimate_base, sigma_m=inputs.sigma_m, loss=inputs.loss,
            train_fraction=settings.train_fraction,
        )
    except InputError as exc:
        if exc.source is not None:
            raise
        raise InputError(exc.found, exc.expected, source=inputs.measurements_path) from None


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    inputs = resolve_inputs(args)
    robot, measurements_path = inputs.robot, inputs.measurements_path
    everything = args.method.strip().lower() == "all"
    methods = list(SOLVERS) if everything else [get_solver(args.method).name]
    measurements = load_measurements(measurements_path, robot, stdin=True)
    if args.errors == (AUTO,):
        if everything:
            raise InputError("--errors auto with --method all", "one method to compare the "
                             "error models with", source="--errors")
        return _run_auto(args, inputs, measurements)
    split = make_split(inputs, measurements, args.seed)
    if measurements.kind != "point":  # random poses reach no common point: no reference rank
        warn_rank_deficient(robot, split, measurements_path, args.seed)
    rank = measurement_identifiability(split.problem.model, split.problem.x0,
                                       split.problem.train).rank
    warn_few_poses(len(split.train_rows), rank, inputs.calibration.errors,
                   split.problem.model.kind.rows_per_pose)
    truth = None
    if inputs.truth_path is not None and inputs.truth_path.exists():
        truth = load_truth_delta(inputs.truth_path, robot.n_joints, robot.is_length)
    fallback_dir = args.json.parent if args.json else None
    with calibration_log(args, methods, robot, split.problem.model.rig, measurements, truth,
                         fallback_dir=fallback_dir) as live:
        results = solve_many(robot, split, methods, seed=args.seed,
                             budget=inputs.calibration.budget,
                             on_result=None if live is None else live.add)
        if len(results) == 1:
            (result,) = results.values()
            misfit = result.misfit is not None and result.misfit.misfit
            causes = likely_causes(split, result) if misfit else ()
            truth, errors = truth_of(inputs, result)
            print(format_result(result, truth, truth=errors, causes=causes))
            document = result_to_dict(result, causes=causes, truth=errors)
        else:
            print(format_comparison(results))
            document = {"methods": {name: result_to_dict(r) for name, r in results.items()}}
        if args.json:
            write_json(args.json, document)
        if live is not None:
            live.finish(results)
    return 0


def _run_auto(args: argparse.Namespace, inputs: Inputs, measurements: Measurements) -> int:
    """Fit the nested error models, print the comparison and the chosen one's result."""
    settings = inputs.calibration
    if len(inputs.rig.ports_m) != 1 or measurements.kind != "length":
        raise InputError("--errors auto with this rig", "cable lengths from one port",
                         source="--errors")
    try:
        choice = choose_errors(
            inputs.robot, measurements, inputs.rig, method=get_solver(args.method).name,
            seed=args.seed, estimate_port=settings.estimate_port,
            estimate_offset=settings.estimate_offset, budget=settings.budget,
            train_fraction=settings.train_fraction)
    except InputError as exc:
        if exc.source is not None:
            raise
        raise InputError(exc.found, exc.expected, source=inputs.measurements_path) from None
    print(format_choice(choice))
    print()
    print(format_result(choice.best.result))
    if args.json:
        write_json(args.json, {**result_to_dict(choice.best.result),
                               "error_choice": choice_to_dict(choice)})
    return 0
