"""`twin virtual-controller`: a simulated ABB controller speaking Robot Web Services on
loopback."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from twin.cli.arguments import add_scenario, integer, number
from twin.hardware.rws.protocol import (
    FACTORY_PASSWORD,
    FACTORY_USER,
    PASSWORD_VARIABLE,
    USER_VARIABLE,
)
from twin.io.paths import InputPath

NAME = "virtual-controller"
HELP = "serve a simulated ABB controller (Robot Web Services) on loopback"
DESCRIPTION = (
    "Answer on 127.0.0.1 as an ABB controller does over Robot Web Services (RWS 1.0: HTTP, "
    "digest; --rws2: RWS 2.0, HTTPS, basic), running the RAPID plan module once its file "
    "exists: it moves to each pose of the plan, tells the virtual encoder (the same "
    "--pose-file as twin virtual-encoder's) and waits for twin capture's acknowledgement. "
    "Prints the --robot-source URL as its first line, then serves until stopped."
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The subcommand's arguments."""
    add_scenario(parser)
    parser.add_argument("--module", type=Path, metavar="FILE.mod",
                        help="the RAPID plan module to run once the file exists (twin capture "
                        "writes it as OUT/TwinPlan.mod); without it the robot only jogs")
    parser.add_argument("--pose-file", type=Path, metavar="FILE",
                        help="where the robot's pose is published for twin virtual-encoder "
                        "(default: the same file as its default)")
    parser.add_argument("--listen", type=integer(0, 65535), default=0, metavar="PORT",
                        help="TCP port on 127.0.0.1 (default: 0, any free port)")
    parser.add_argument("--rws2", action="store_true",
                        help="RWS 2.0 (OmniCore): HTTPS with --cert and --key, basic auth")
    parser.add_argument("--cert", type=InputPath, metavar="CERT.pem",
                        help="rws2: the server's certificate chain")
    parser.add_argument("--key", type=InputPath, metavar="KEY.pem", help="rws2: its key")
    parser.add_argument("--move-time", type=number(0.0, 60.0, above=True), default=0.1,
                        metavar="S", help="duration of each move (default: 0.1 s)")
    parser.add_argument("--refuse-pose", type=integer(0, 100000), default=0, metavar="K",
                        help="fault: stop the program before pose K (default: none)")
    parser.add_argument("--creep-pose", type=integer(0, 100000), default=0, metavar="K",
                        help="fault: joint 1 keeps creeping at pose K (default: none)")


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    from twin.hardware.robot_sources.sim import DEFAULT_POSE_FILE
    from twin.hardware.rws.virtual_controller import ControllerSettings, Robot, serve
    from twin.io.rapid import refuse_prismatic
    from twin.scenario import load_scenario
    from twin.units import rad_to_deg

    robot = load_scenario(args.scenario).robot
    refuse_prismatic(robot.joint_names, robot.prismatic, args.scenario)
    settings = ControllerSettings(
        robot.n_joints, tuple(float(v) for v in rad_to_deg(robot.lower_rad)),
        tuple(float(v) for v in rad_to_deg(robot.upper_rad)), args.module,
        args.pose_file or DEFAULT_POSE_FILE, args.move_time, args.refuse_pose,
        args.creep_pose)
    tls = (args.cert, args.key) if args.cert is not None and args.key is not None else None

    def announce(url: str) -> None:
        print(url, flush=True)

    serve(Robot(settings), 2 if args.rws2 else 1,
          os.environ.get(USER_VARIABLE) or FACTORY_USER,
          os.environ.get(PASSWORD_VARIABLE) or FACTORY_PASSWORD, port=args.listen, tls=tls,
          announce=announce)
    return 0
