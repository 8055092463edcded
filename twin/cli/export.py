"""`twin export`: the identified robot as a D-H model file, a URDF, an MJCF, a UR calibration
file (``ur-calibration``, with ``--base`` the user's own kept) or xacro properties."""

from __future__ import annotations

import argparse
import warnings
from dataclasses import replace

from twin.cli.arguments import (
    RESULT_ROBOT,
    add_output,
    add_result,
    add_robot_flags,
    add_temperature,
    given_robot,
)
from twin.errors import InputError, UnknownChoiceError
from twin.export import FORMATS, export_text
from twin.io.paths import InputPath, read_text
from twin.unknowns import ERRORS

NAME = "export"
HELP = "write the identified robot as a D-H model, URDF, MJCF, UR calibration or xacro"
DESCRIPTION = (
    "Add the D-H errors of a calibration result to the nominal robot and write "
    "the identified robot as a model TOML (dh: mm and degrees, usable with --robot), a "
    "URDF (ROS, Pinocchio; link 'flange'), an MJCF (MuJoCo; site 'flange'), a UR robot's "
    "kinematics file in ur_calibration's layout (ur-calibration; --base keeps the hash and "
    "comments of the robot's own), or xacro properties a description includes (xacro). "
    "The rig's unknowns (ports, length offset, the encoder's scale) are the instrument's, "
    "not the robot's: robot files leave them out."
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The subcommand's arguments."""
    add_result(parser, positional=True)
    add_robot_flags(parser, RESULT_ROBOT)
    parser.add_argument("--method", help="result to use from a `--method all` result file")
    parser.add_argument("--format", required=True, dest="format_name",
                        help="one of " + ", ".join(FORMATS))
    add_output(parser, "FILE", "output file")
    parser.add_argument("--base", type=InputPath, metavar="KINEMATICS.yaml",
                        help="with ur-calibration: the file ur_calibration extracted from the "
                        "robot; its hash, comments and order are kept, its numbers replaced")
    add_temperature(parser, "the exported table")


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    from twin.io.atomic import write_atomic
    from twin.io.identified import (
        ResultWarning,
        at_temperature,
        load_result,
        result_groups,
        warn_result_cautions,
        warn_temperature,
    )
    from twin.report.display import plain

    if args.format_name not in FORMATS:
        raise UnknownChoiceError("export format", args.format_name, FORMATS, source="--format")
    result = load_result(args.result, given_robot(args), args.method)
    loaded = at_temperature(result, args.temperature_c, args.result)
    robot, delta = loaded.robot, loaded.delta
    # The growth is applied (--temperature-c) or warned about below, apart from the rest.
    joint_level = [name for name in result_groups(args.result, args.method)
                   if name in ERRORS and name not in ("dh", "thermal")]
    if joint_level:
        warnings.warn(f"{args.result}: a {args.format_name} file holds the identified D-H table "
                      f"only, not the joint-level errors ({', '.join(joint_level)}) the result "
                      "also has: use twin compensate or twin predict with the result itself",
                      ResultWarning, stacklevel=2)
    if args.base is not None and args.format_name != "ur-calibration":
        raise InputError(f"--base with --format {args.format_name}",
                         "it with --format ur-calibration", source="--base")
    at = "" if args.temperature_c is None else f", at {plain(args.temperature_c, 2)} °C"
    identified = replace(robot.perturbed(delta), name=f"{result.robot.name} (identified{at})")
    if args.base is not None:
        from twin.export.ur_calibration import export_with_base

        text = export_with_base(identified, read_text(args.base, "a ur_calibration YAML file"),
                                str(args.base))
    else:
        text = export_text(identified, args.format_name)
    # After every input is checked: a refusal stays one line.
    warn_result_cautions(args.result, args.method, f"the {args.format_name} file")
    warn_temperature(result, args.temperature_c, args.result, f"the {args.format_name} file")
    write_atomic(args.out, text)
    print(f"wrote {args.out} ({args.format_name}, {identified.name})")
    if args.format_name == "xacro":
        print(f'include it in the description: <xacro:include filename="{args.out}"/>, and write '
              'each joint\'s origin as xyz="${JOINT_origin_xyz}" rpy="${JOINT_origin_rpy}"')
    return 0
