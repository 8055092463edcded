"""`twin export`: the identified robot as a D-H model file, a URDF or an MJCF."""

from __future__ import annotations

import argparse
import warnings
from dataclasses import replace
from typing import Any

from twin.cli.arguments import add_robot_flags, robot_from_flags
from twin.errors import UnknownChoiceError
from twin.export import FORMATS, export_text
from twin.io.atomic import write_atomic
from twin.io.identified import ResultWarning, load_result_delta, result_groups
from twin.io.paths import InputPath, OutputFile
from twin.unknowns import ERRORS


def add_parser(subparsers: Any) -> None:
    """Register the subcommand."""
    parser = subparsers.add_parser(
        "export",
        help="write the identified robot as a D-H model, URDF or MJCF",
        description="Add the D-H errors of a calibration result to the nominal robot and write "
        "the identified robot as a model TOML (dh: mm and degrees, usable with --robot), a "
        "URDF (ROS, Pinocchio; link 'flange') or an MJCF (MuJoCo; site 'flange').",
    )
    parser.add_argument("result", type=InputPath, metavar="RESULT.json",
                        help="calibration result written by `twin calibrate --json`")
    add_robot_flags(parser, "the nominal robot the result was identified for")
    parser.add_argument("--method", help="result to use from a `--method all` result file")
    parser.add_argument("--format", required=True, dest="format_name",
                        help="one of " + ", ".join(FORMATS))
    parser.add_argument("--out", type=OutputFile, required=True, metavar="FILE",
                        help="output file")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    if args.format_name not in FORMATS:
        raise UnknownChoiceError("export format", args.format_name, FORMATS, source="--format")
    robot = robot_from_flags(args)
    delta = load_result_delta(args.result, robot, args.method)
    joint_level = [name for name in result_groups(args.result, args.method)
                   if name in ERRORS and name != "dh"]
    if joint_level:
        warnings.warn(f"{args.result}: a {args.format_name} file holds the identified D-H table "
                      f"only, not the joint-level errors ({', '.join(joint_level)}) the result "
                      "also has: use twin compensate or twin predict with the result itself",
                      ResultWarning, stacklevel=2)
    identified = replace(robot.perturbed(delta), name=f"{robot.name} (identified)")
    write_atomic(args.out, export_text(identified, args.format_name))
    print(f"wrote {args.out} ({args.format_name}, {identified.name})")
    return 0
