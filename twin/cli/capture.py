"""`twin capture`: measure a pose plan with a real (or virtual) encoder, durably."""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

from twin.choices import JOINT_RANGE
from twin.cli.arguments import (
    add_cable_tension,
    add_output,
    add_seed,
    integer,
    number,
    pause,
    seconds,
)
from twin.hardware.rws.protocol import PASSWORD_VARIABLE, USER_VARIABLE
from twin.io.paths import CAPTURE_FOLDER, InputPath

MAX_READINGS = 1000
"""Most readings --settle-k and --max-failures may ask for."""


NAME = "capture"
HELP = "measure a pose plan with the drawstring encoder"
DESCRIPTION = (
    "Bring the robot to each pose of a plan, read the encoder until the length "
    "settles, and append the pose to OUT/measurements.csv (fsync-ed before the next pose). "
    "Also writes OUT/capture.toml for `twin calibrate`. Interrupted, it keeps every "
    "measured pose; the same command again resumes at the first missing one."
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The subcommand's arguments."""
    parser.add_argument("--plan", type=InputPath, required=True, metavar="PLAN.csv",
                        help="poses to measure: CSV with the robot's q1..qN in degrees")
    parser.add_argument("--encoder", required=True, metavar="URL|DEVICE.toml",
                        help="serial:///dev/ttyUSB0?baud=115200&protocol=ascii or a device "
                        "TOML file")
    parser.add_argument("--robot-source", required=True, metavar="SOURCE",
                        help="sim: the twin moves (with twin virtual-encoder); manual: the "
                        "operator jogs and confirms; file: joint angles logged by the "
                        "controller; rws://HOST[:PORT]: an ABB IRC5 (RWS 1.0), "
                        "rws2://HOST[:PORT]: an ABB OmniCore (RWS 2.0)")
    add_output(parser, "DIR", "output folder", folder=CAPTURE_FOLDER)
    parser.add_argument("--robot", type=InputPath, help=f"robot model TOML or URDF, {JOINT_RANGE} "
                        "joints (default: the ABB IRB 120; with sim: the scenario's)")
    parser.add_argument("--port", help="encoder port X,Y,Z in mm, robot base frame (with sim: "
                        "the scenario's told port)")
    parser.add_argument("--attachment", metavar="X,Y,Z", help="where the cable hooks on, mm "
                        "in the flange frame (an eyelet; default 0,0,0: the flange centre; "
                        "with sim: the scenario's told attachment)")
    add_cable_tension(parser, "the encoder spring's pull on the cable in newtons, recorded "
                      "for the calibration's compliance group (default 0; with sim: the "
                      "scenario's)")
    parser.add_argument("--scenario", type=InputPath, metavar="SCENARIO.toml",
                        help="sim: the scenario the virtual encoder serves")
    add_seed(parser, "sim: the virtual encoder's --seed")
    add_output(parser, "FILE", "sim: the virtual encoder's --pose-file", flag="--pose-file",
               required=False)
    parser.add_argument("--joint-log", type=InputPath, metavar="LOG.csv",
                        help="file: the controller's log, columns pose,q1..qN (deg)")
    parser.add_argument("--joint-log-wait", type=seconds(zero=True), default=60.0, metavar="S",
                        help="file: how long to wait for a pose's row, or none (default: 60 s)")
    parser.add_argument("--settle-k", type=integer(1, MAX_READINGS), default=5, metavar="K",
                        help="consecutive readings that must agree (default: 5)")
    parser.add_argument("--settle-tol", type=number(0.0, 1000.0), default=0.01, metavar="MM",
                        help="largest spread of those readings, mm (default: 0.01)")
    parser.add_argument("--settle-timeout", type=seconds(zero=False), default=10.0,
                        metavar="S", help="longest wait for the length to settle, or none to "
                        "wait until it does (default: 10 s)")
    parser.add_argument("--settle-interval", type=pause, default=0.0, metavar="S",
                        help="pause between readings, for devices with a slow update rate "
                        "(default: 0 s)")
    parser.add_argument("--max-failures", type=integer(1, MAX_READINGS), default=5,
                        metavar="N", help="failed readings in a row before giving up "
                        "(default: 5)")
    parser.add_argument("--reconnect", type=seconds(zero=True), default=5.0, metavar="S",
                        help="how long to try reopening a lost port or reaching a lost "
                        "controller, or none to keep trying (default: 5 s)")
    add_rws_arguments(parser)


def add_rws_arguments(parser: argparse.ArgumentParser) -> None:
    """The flags of an ABB controller as the robot source."""
    group = parser.add_argument_group("ABB controller (rws://, rws2://)")
    group.add_argument("--rws-user", metavar="NAME", help=f"the RWS user (default: "
                       f"${USER_VARIABLE}, else ABB's factory user)")
    group.add_argument("--rws-password", metavar="PASSWORD", help=f"its password (default: "
                       f"${PASSWORD_VARIABLE}, else the factory one; never printed)")
    group.add_argument("--ca-file", type=InputPath, metavar="CA.pem", help="rws2: the CA "
                       "the controller's certificate is checked against")
    group.add_argument("--insecure", action="store_true", help="rws2: do not check the "
                       "controller's certificate")
    group.add_argument("--jog", action="store_true", help="no plan module runs: the operator "
                       "jogs to each pose and twin reads the joints once they stand still")
    group.add_argument("--joint-tol", type=number(0.0, 10.0, above=True), default=0.05,
                       metavar="DEG", help="largest difference between a joint read and the "
                       "plan's (default: 0.05 deg; jogging needs more, e.g. 0.5)")
    group.add_argument("--standstill", type=number(0.0, 60.0, above=True), default=0.3,
                       metavar="S", help="how long the joints must stay within "
                       "--standstill-tol to count as stopped (default: 0.3 s)")
    group.add_argument("--standstill-tol", type=number(0.0, 1.0, above=True), default=0.001,
                       metavar="DEG", help="largest spread of a joint over that window "
                       "(default: 0.001 deg)")
    group.add_argument("--robot-wait", type=seconds(zero=False), default=120.0, metavar="S",
                       help="longest wait for the robot to stand at a pose, or none "
                       "(default: 120 s)")


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    from twin.hardware.capture_request import CaptureRequest, capture_request
    from twin.hardware.encoders.settle import SettleRule
    from twin.hardware.robot_sources import SourceRequest
    from twin.units import mm_to_m

    rule = SettleRule(k=args.settle_k, tolerance_m=float(mm_to_m(args.settle_tol)),
                      timeout_s=args.settle_timeout, max_failures=args.max_failures,
                      interval_s=args.settle_interval)
    source = SourceRequest(args.robot_source, pose_file=args.pose_file,
                           joint_log=args.joint_log, joint_log_wait_s=args.joint_log_wait,
                           prompt_out=sys.stdout, answers_in=sys.stdin, **_rws(args))
    request = CaptureRequest(args.plan, args.encoder, args.out, source, rule, robot=args.robot,
                             port_mm=args.port, attachment_mm=args.attachment,
                             cable_tension_n=args.cable_tension, scenario=args.scenario,
                             seed=args.seed, reconnect_s=args.reconnect)
    outcome = capture_request(request, report=lambda line: print(line, flush=True))
    print(f"measured {outcome.measured} poses; all {outcome.n_poses} are in "
          f"{outcome.measurements}")
    print(f"calibrate with: twin calibrate {outcome.capture}")
    return 0


def _rws(args: argparse.Namespace) -> dict[str, Any]:
    """The ABB controller's connection and capture settings, for an rws:// source."""
    if not args.robot_source.startswith(("rws://", "rws2://")):
        return {}
    from twin.hardware.robot_sources.rws import RwsCapture
    from twin.hardware.rws.client import RwsConnection

    connection = RwsConnection.from_spec(
        args.robot_source, user=args.rws_user, password=args.rws_password,
        ca_file=args.ca_file, insecure=args.insecure,
        retry_s=math.inf if args.reconnect is None else args.reconnect)
    settings = RwsCapture(joint_tol_deg=args.joint_tol, standstill_s=args.standstill,
                          standstill_tol_deg=args.standstill_tol, wait_s=args.robot_wait,
                          jog=args.jog)
    return {"rws": connection, "options": {"rws": settings}}
