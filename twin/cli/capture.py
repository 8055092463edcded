"""`twin capture`: measure a pose plan with a real (or virtual) encoder, durably."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from twin.cli.arguments import (
    add_cable_tension,
    add_output,
    add_seed,
    integer,
    number,
    pause,
    seconds,
)
from twin.io.paths import InputPath

ROBOT_SOURCES = ("sim", "manual", "file")
CAPTURE_JOINTS = 6
"""Joints of the arms twin capture records (its journal's columns are q1..q6)."""
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
                        help="poses to measure: CSV with q1..q6 in degrees")
    parser.add_argument("--encoder", required=True, metavar="URL|DEVICE.toml",
                        help="serial:///dev/ttyUSB0?baud=115200&protocol=ascii or a device "
                        "TOML file")
    parser.add_argument("--robot-source", choices=ROBOT_SOURCES, required=True,
                        help="sim: the twin moves (with twin virtual-encoder); manual: the "
                        "operator jogs and confirms; file: joint angles logged by the controller")
    add_output(parser, "DIR", "output folder", folder=True)
    parser.add_argument("--robot", type=InputPath, help="6-joint robot model TOML (default: "
                        "the ABB IRB 120; with sim: the scenario's)")
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
                        help="file: the controller's log, columns pose,q1..q6 (deg)")
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
                        help="how long to try reopening a lost port, or none to keep trying "
                        "(default: 5 s)")


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    from twin.calibration.settings import CalibrationSettings
    from twin.errors import InputError
    from twin.hardware.capture_session import CAPTURE_NAME, MEASUREMENTS_NAME, capture_folder
    from twin.hardware.encoders import resolve
    from twin.hardware.encoders.settle import SettleRule
    from twin.hardware.robot_sources.base import RobotSource
    from twin.io.capture_file import parse_port_mm
    from twin.io.measurements import load_plan
    from twin.io.robot_file import load_robot_or_default
    from twin.rig import Rig
    from twin.units import mm_to_m

    config = resolve(args.encoder)
    rule = SettleRule(k=args.settle_k, tolerance_m=float(mm_to_m(args.settle_tol)),
                      timeout_s=args.settle_timeout, max_failures=args.max_failures,
                      interval_s=args.settle_interval)
    truth = calibration = None
    if args.robot_source == "sim":
        given = [flag for flag, value in (("--robot", args.robot), ("--port", args.port),
                                          ("--attachment", args.attachment),
                                          ("--cable-tension", args.cable_tension))
                 if value is not None]
        if given:
            raise InputError(f"{' and '.join(given)} with --robot-source sim", "none of "
                             "--robot, --port, --attachment, --cable-tension: the scenario "
                             "gives the robot and the rig", source="command line")
        if args.scenario is None:
            raise InputError("no --scenario", "the scenario the virtual encoder serves "
                             "(--robot-source sim)", source="command line")
        from twin.scenario import load_scenario
        from twin.sim import simulate

        sim = simulate(load_scenario(args.scenario), args.seed)
        if sim.port_m is None or sim.port_nominal_m is None or len(sim.rig.ports_m) > 1:
            raise InputError(f"a {sim.measurements.kind} scenario with "
                             f"{len(sim.rig.ports_m)} ports", "a scenario of one cable port "
                             "(the virtual encoder serves one cable)", source=args.scenario)
        robot, rig, truth = sim.robot, sim.rig_told_pulled, sim.capture_truth
        calibration = sim.scenario.calibration
    else:
        robot = load_robot_or_default(args.robot)
        if args.port is None:
            raise InputError("no --port", "the encoder port as --port X,Y,Z in mm",
                             source="command line")
        rig = Rig.cable(parse_port_mm(args.port, "--port", ""),
                        None if args.attachment is None
                        else parse_port_mm(args.attachment, "--attachment", ""),
                        tension_n=args.cable_tension or 0.0)
        if args.cable_tension:
            calibration = CalibrationSettings()
    if robot.urdf is not None or robot.n_joints != CAPTURE_JOINTS:
        # The capture journal's columns are pose, q1..q6, length (twin.hardware.capture_session).
        raise InputError(f"a {robot.n_joints}-joint robot"
                         + (" from a URDF" if robot.urdf is not None else ""),
                         f"a {CAPTURE_JOINTS}-joint robot model TOML (twin capture records "
                         "q1..q6)", source=args.scenario or args.robot or "the IRB 120")
    plan_q_rad, _ = load_plan(args.plan, robot)

    source: RobotSource
    if args.robot_source == "sim":
        from twin.hardware.robot_sources.sim import DEFAULT_POSE_FILE, SimRobot

        source = SimRobot(plan_q_rad, args.pose_file or DEFAULT_POSE_FILE)
    elif args.robot_source == "manual":
        from twin.hardware.robot_sources.manual import ManualRobot

        source = ManualRobot(sys.stdout, sys.stdin)
    else:
        from twin.hardware.robot_sources.file import FileRobot

        if args.joint_log is None:
            raise InputError("no --joint-log", "the controller's log CSV (--robot-source file)",
                             source="command line")
        source = FileRobot(args.joint_log, wait_s=args.joint_log_wait)

    out: Path = args.out
    measured = capture_folder(out, args.plan, plan_q_rad, robot, rig, config, source, rule,
                              calibration=calibration, truth=truth, reconnect_s=args.reconnect,
                              report=lambda line: print(line, flush=True))
    print(f"measured {measured} poses; all {len(plan_q_rad)} are in {out / MEASUREMENTS_NAME}")
    print(f"calibrate with: twin calibrate {out / CAPTURE_NAME}")
    return 0
