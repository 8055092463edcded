"""`twin calibrate`: identify the D-H errors from a measurement file or a capture."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from twin.calibration import calibrate_many
from twin.errors import InputError
from twin.io.capture import load_capture, parse_port_mm
from twin.io.measurements import load_measurements
from twin.io.results import result_to_dict, write_json
from twin.io.truth import load_truth_delta
from twin.report import format_comparison, format_result
from twin.robot import default_robot, load_robot
from twin.solvers import SOLVERS, solver_choices


def add_parser(subparsers: Any) -> None:
    """Register the subcommand."""
    parser = subparsers.add_parser(
        "calibrate",
        help="identify the D-H errors from cable measurements",
        description="Identify the D-H errors of a robot from drawstring-encoder measurements. "
        "INPUT is a measurement CSV (q1..q6 in degrees, length in mm; needs --port) or a "
        "capture.toml written by `twin simulate` or `twin capture`.",
    )
    parser.add_argument("input", type=Path, metavar="INPUT",
                        help="MEASUREMENTS.csv or capture.toml")
    parser.add_argument("--robot", type=Path, help="robot model TOML (default: the ABB IRB 120)")
    parser.add_argument("--port", help="encoder port X,Y,Z in mm, robot base frame")
    parser.add_argument(
        "--method", default="lm",
        help="method name or paper alias, or 'all': " + ", ".join(solver_choices()),
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the split and of the method")
    parser.add_argument("--estimate-port", action="store_true",
                        help="also identify a correction of the port position")
    parser.add_argument("--estimate-offset", action="store_true",
                        help="also identify an unknown cable-length offset")
    parser.add_argument("--json", type=Path, metavar="OUT.json", help="write the result as JSON")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    truth_path = None
    if args.input.suffix == ".toml":
        capture = load_capture(args.input)
        robot = load_robot(args.robot) if args.robot else capture.robot
        port_m = parse_port_mm(args.port, "--port", "") if args.port else capture.port_m
        measurements_path = capture.measurements
        truth_path = capture.truth
    else:
        robot = load_robot(args.robot) if args.robot else default_robot()
        if args.port is None:
            raise InputError("no --port", "the encoder port as --port X,Y,Z in mm (or a "
                             "capture.toml as INPUT)", source=args.input)
        port_m = parse_port_mm(args.port, "--port", "")
        measurements_path = args.input
    methods = list(SOLVERS) if args.method.strip().lower() == "all" else [args.method]
    measurements = load_measurements(measurements_path, robot)
    try:
        results = calibrate_many(
            robot, measurements, port_m, methods, seed=args.seed,
            estimate_port=args.estimate_port, estimate_offset=args.estimate_offset,
        )
    except InputError as exc:
        if exc.source is not None:
            raise
        raise InputError(exc.found, exc.expected, source=measurements_path) from None
    truth = None
    if truth_path is not None and truth_path.exists():
        truth = load_truth_delta(truth_path, robot.n_joints)
    if len(results) == 1:
        (result,) = results.values()
        print(format_result(result, truth))
        document = result_to_dict(result)
    else:
        print(format_comparison(results))
        document = {"methods": {name: result_to_dict(r) for name, r in results.items()}}
    if args.json:
        write_json(args.json, document)
    return 0
