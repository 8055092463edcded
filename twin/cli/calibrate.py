"""`twin calibrate`: identify the robot's errors from a measurement file or a capture.

``--errors`` chooses the robot's error groups (D-H by default; transmission, backlash and
compliance beside it), or ``auto`` fits nested choices and keeps the one the data support
(:mod:`twin.selection`).
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from twin.calibration import TRAIN_FRACTION, SplitProblem, make_problem, solve_many
from twin.cli.arguments import (
    AUTO,
    add_robot_flags,
    error_groups,
    integer,
    number,
    robot_from_flags,
    seed,
    share,
)
from twin.dataset import Measurements
from twin.errors import InputError
from twin.identifiability import RankWarning, measurement_identifiability, spread_rank
from twin.io.capture_file import CalibrationSettings, load_capture, parse_port_mm
from twin.io.measurements import load_measurements
from twin.io.paths import InputPath, OutputFile
from twin.io.results import choice_to_dict, result_to_dict, write_json
from twin.io.truth import load_truth_delta
from twin.report import format_choice, format_comparison, format_result
from twin.rig import MAX_TENSION_N, Rig
from twin.robot import RobotModel, default_robot
from twin.selection import choose_errors, warn_few_poses
from twin.solvers import SOLVERS, get_solver, solver_choices
from twin.stopping import MAX_ITERATIONS, PROTOCOLS
from twin.unknowns import ERRORS
from twin.viz import add_rerun_flags, calibration_log


def add_parser(subparsers: Any) -> None:
    """Register the subcommand."""
    parser = subparsers.add_parser(
        "calibrate",
        help="identify the D-H errors from cable measurements",
        description="Identify the D-H errors of a robot from drawstring-encoder measurements. "
        "INPUT is a measurement CSV (q1..qN in degrees, length in mm; needs --port) or a "
        "capture.toml written by `twin simulate` or `twin capture`.",
    )
    parser.add_argument("input", type=InputPath, metavar="INPUT",
                        help="MEASUREMENTS.csv (- for standard input) or capture.toml")
    add_robot_flags(parser)
    parser.add_argument("--port", help="encoder port X,Y,Z in mm, robot base frame")
    parser.add_argument(
        "--method", default="lm",
        help="method name or paper alias, or 'all': " + ", ".join(solver_choices()),
    )
    parser.add_argument("--seed", type=seed, default=0,
                        help="seed of the split and of the method")
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
    parser.add_argument("--estimate-port", action="store_true",
                        help="also identify a correction of the port position")
    parser.add_argument("--estimate-offset", action="store_true",
                        help="also identify an unknown cable-length offset")
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


class Inputs(NamedTuple):
    """What INPUT, --robot and --port resolve to."""

    robot: RobotModel
    port_m: NDArray[np.float64]
    """Encoder port, base frame, shape (3,), m."""
    measurements_path: Path
    truth_path: Path | None
    calibration: CalibrationSettings


def resolve_inputs(args: argparse.Namespace) -> Inputs:
    """The robot, port, files and calibration settings named by a capture.toml or a CSV with
    --robot and --port; flags win over the capture's ``[calibration]`` table.

    Raises:
        InputError: if a CSV comes without --port, or a file is wrong.
    """
    input_path, port = args.input, args.port
    named = robot_from_flags(args)
    fraction = getattr(args, "train_fraction", None)
    stop, limit = getattr(args, "stop", None), getattr(args, "max_iterations", None)
    errors = getattr(args, "errors", None)
    errors = None if errors == (AUTO,) else errors
    tension = getattr(args, "cable_tension", None)
    if input_path.suffix == ".toml":
        capture = load_capture(input_path)
        settings = capture.calibration
        return Inputs(
            robot=named if named is not None else capture.robot,
            port_m=parse_port_mm(port, "--port", "") if port else capture.port_m,
            measurements_path=capture.measurements,
            truth_path=capture.truth,
            calibration=CalibrationSettings(
                estimate_port=args.estimate_port or settings.estimate_port,
                estimate_offset=args.estimate_offset or settings.estimate_offset,
                train_fraction=fraction or settings.train_fraction,
                stop=stop or settings.stop,
                max_iterations=limit or settings.max_iterations,
                errors=errors or settings.errors,
                cable_tension_n=settings.cable_tension_n if tension is None else tension,
            ),
        )
    if port is None:
        raise InputError("no --port", "the encoder port as --port X,Y,Z in mm (or a "
                         "capture.toml as INPUT)", source=input_path)
    return Inputs(
        robot=named if named is not None else default_robot(),
        port_m=parse_port_mm(port, "--port", ""),
        measurements_path=input_path,
        truth_path=None,
        calibration=CalibrationSettings(
            estimate_port=args.estimate_port, estimate_offset=args.estimate_offset,
            train_fraction=fraction or TRAIN_FRACTION, stop=stop or PROTOCOLS[0],
            max_iterations=limit, errors=errors or ("dh",), cable_tension_n=tension or 0.0,
        ),
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


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    robot, port_m, measurements_path, truth_path, settings = resolve_inputs(args)
    everything = args.method.strip().lower() == "all"
    methods = list(SOLVERS) if everything else [get_solver(args.method).name]
    measurements = load_measurements(measurements_path, robot, stdin=True)
    rig = Rig.cable(port_m, tension_n=settings.cable_tension_n)
    if args.errors == (AUTO,):
        if everything:
            raise InputError("--errors auto with --method all", "one method to compare the "
                             "error models with", source="--errors")
        return _run_auto(args, robot, rig, measurements, measurements_path, settings)
    try:
        split = make_problem(
            robot, measurements, rig=rig, errors=settings.errors, seed=args.seed,
            estimate_port=settings.estimate_port, estimate_offset=settings.estimate_offset,
            train_fraction=settings.train_fraction,
        )
    except InputError as exc:
        if exc.source is not None:
            raise
        raise InputError(exc.found, exc.expected, source=measurements_path) from None
    warn_rank_deficient(robot, split, measurements_path, args.seed)
    rank = measurement_identifiability(split.problem.model, split.problem.x0,
                                       split.problem.train).rank
    warn_few_poses(len(split.train_rows), rank, settings.errors)
    truth = None
    if truth_path is not None and truth_path.exists():
        truth = load_truth_delta(truth_path, robot.n_joints, robot.is_length)
    fallback_dir = args.json.parent if args.json else None
    with calibration_log(args, methods, robot, port_m, measurements, truth,
                         fallback_dir=fallback_dir) as live:
        results = solve_many(robot, split, methods, seed=args.seed, budget=settings.budget,
                             on_result=None if live is None else live.add)
        if len(results) == 1:
            (result,) = results.values()
            print(format_result(result, truth))
            document = result_to_dict(result)
        else:
            print(format_comparison(results))
            document = {"methods": {name: result_to_dict(r) for name, r in results.items()}}
        if args.json:
            write_json(args.json, document)
        if live is not None:
            live.finish(results)
    return 0


def _run_auto(args: argparse.Namespace, robot: RobotModel, rig: Rig,
              measurements: Measurements, measurements_path: Path,
              settings: CalibrationSettings) -> int:
    """Fit the nested error models, print the comparison and the chosen one's result."""
    try:
        choice = choose_errors(
            robot, measurements, rig, method=get_solver(args.method).name, seed=args.seed,
            estimate_port=settings.estimate_port, estimate_offset=settings.estimate_offset,
            budget=settings.budget, train_fraction=settings.train_fraction)
    except InputError as exc:
        if exc.source is not None:
            raise
        raise InputError(exc.found, exc.expected, source=measurements_path) from None
    print(format_choice(choice))
    print()
    print(format_result(choice.best.result))
    if args.json:
        write_json(args.json, {**result_to_dict(choice.best.result),
                               "error_choice": choice_to_dict(choice)})
    return 0
