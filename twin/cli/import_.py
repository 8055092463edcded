"""`twin import`: other tools' recordings into twin's measurement CSV."""

from __future__ import annotations

import argparse

from twin.choices import ANGLE_UNITS, LENGTH_UNITS, SESSION_BY
from twin.cli.arguments import add_output, number
from twin.io.paths import InputPath

NAME = "import"
HELP = "turn ROS bags and other CSV files into twin's measurement CSV"
DESCRIPTION = (
    "Read a ROS 1 or ROS 2 bag (SQLite or MCAP) with sensor_msgs/JointState and a length "
    "(std_msgs/Float64), point (geometry_msgs/PointStamped) or pose topic, cutting a pose "
    "wherever the joints stood still (the median of each still window), or CSV files in the "
    "units given, with the robot's joint names as columns or no header, one file per fixed "
    "point. Writes OUT.csv in twin's units (degrees, mm); every row left out is listed with "
    "the reason."
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The subcommand's arguments."""
    parser.add_argument("inputs", nargs="+", type=InputPath, metavar="INPUT",
                        help="a bag (a ROS 1 .bag, a ROS 2 bag folder or its .db3/.mcap), or "
                        "CSV files")
    parser.add_argument("--robot", type=InputPath, metavar="ROBOT.toml|URDF",
                        help="the robot: its joint names and limits (default: the IRB 120)")
    add_output(parser, "OUT.csv", "the measurement CSV to write")
    parser.add_argument("--angle-unit", choices=ANGLE_UNITS,
                        help="CSV: the unit of the joint angles (required for CSV)")
    parser.add_argument("--length-unit", choices=LENGTH_UNITS, default="mm",
                        help="CSV: the unit of lengths and x,y,z (default: mm)")
    parser.add_argument("--headerless", action="store_true",
                        help="CSV: no header; each row is the joints, then nothing (the file "
                        "is one fixed point), a length, or x,y,z")
    parser.add_argument("--session-by", choices=SESSION_BY,
                        help="CSV: a session column naming each row's file's folder below the "
                        "inputs' common folder (folder: a fixture placement, a day) or its file "
                        "(file): for --cv-by session, and one encoder zero per session of "
                        "cable lengths")
    parser.add_argument("--joints-topic", metavar="TOPIC",
                        help="bag: the JointState topic (default: the bag's only one)")
    parser.add_argument("--reading-topic", metavar="TOPIC",
                        help="bag: the length, point or pose topic (default: the only one)")
    parser.add_argument("--still-tol", type=number(0.0, 10.0, above=True), default=0.01,
                        metavar="DEG", help="bag: largest spread of a joint inside a still "
                        "window (default: 0.01 deg)")
    parser.add_argument("--still-time", type=number(0.0, 3600.0, above=True), default=0.5,
                        metavar="S", help="bag: shortest still window (default: 0.5 s)")


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    from twin.io.importers import StillRule, import_files
    from twin.io.measurements import write_measurements
    from twin.io.robot_file import load_robot_or_default
    from twin.units import deg_to_rad

    robot = load_robot_or_default(args.robot)
    imported = import_files(args.inputs, robot, angle_unit=args.angle_unit,
                            length_unit=args.length_unit, headerless=args.headerless,
                            rule=StillRule(float(deg_to_rad(args.still_tol)), args.still_time),
                            joints_topic=args.joints_topic, reading_topic=args.reading_topic,
                            session_by=args.session_by)
    for line in imported.dropped:
        print(line)
    write_measurements(args.out, imported.measurements, robot)
    measured = imported.measurements
    print(f"imported {len(measured.q_rad)} poses ({measured.kind}) of {robot.name} into "
          f"{args.out}; {len(imported.dropped)} left out")
    return 0
