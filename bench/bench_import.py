"""`twin import` of a bag: messages per second through twin's importer (read, deserialise, cut
poses where the joints stood still, medians) against reading and deserialising the same bag's
messages with rosbags alone.

Run by hand: ``python bench/bench_import.py`` (``--tiny`` for a quick check). The bag is a
ROS 2 SQLite bag written here with rosbags: the IRB 120's joint states at 250 Hz and cable
lengths at 125 Hz, a 1 s move and a 1 s stop per pose. Prints the rates and their ratio.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
from _timing import median_time
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Writer
from rosbags.typesys import Stores, get_typestore

from twin.io.importers import StillRule, import_files
from twin.io.robot_file import default_robot

RATE_HZ = 250


def write_bag(path: Path, poses: int) -> int:
    """A bag of ``poses`` stops; returns its message count."""
    store = get_typestore(Stores.ROS2_HUMBLE)
    types = store.types
    robot = default_robot()
    rng = np.random.default_rng(0)
    targets = rng.uniform(robot.lower_rad * 0.5, robot.upper_rad * 0.5, size=(poses, 6))
    count, clock, previous = 0, 0.0, np.zeros(6)
    with Writer(path, version=9) as writer:
        joints = writer.add_connection("/joint_states", "sensor_msgs/msg/JointState",
                                       typestore=store)
        lengths = writer.add_connection("/length", "std_msgs/msg/Float64", typestore=store)
        for target in targets:
            for share in np.r_[np.arange(1, RATE_HZ + 1) / RATE_HZ, np.ones(RATE_HZ)]:
                q = previous + share * (target - previous)
                stamp = int(clock * 1e9) + 1
                header = types["std_msgs/msg/Header"](
                    stamp=types["builtin_interfaces/msg/Time"](sec=int(clock),
                                                               nanosec=int(clock % 1 * 1e9)),
                    frame_id="base")
                message = types["sensor_msgs/msg/JointState"](
                    header=header, name=list(robot.joint_names), position=q,
                    velocity=np.zeros(0), effort=np.zeros(0))
                writer.write(joints, stamp, store.serialize_cdr(message, message.__msgtype__))
                count += 1
                if count % 2:
                    length = types["std_msgs/msg/Float64"](data=0.8 + 0.1 * share)
                    writer.write(lengths, stamp, store.serialize_cdr(length,
                                                                     length.__msgtype__))
                    count += 1
                clock += 1 / RATE_HZ
            previous = target
    return count


def read_alone(path: Path) -> int:
    """Every message read and deserialised with rosbags alone."""
    count = 0
    with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        for connection, _, raw in reader.messages():
            reader.deserialize(raw, connection.msgtype)
            count += 1
    return count


def main() -> None:
    """Print the rates of both readers and their ratio."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--tiny", action="store_true", help="5 poses, one repeat")
    args = parser.parse_args()
    poses, repeats = (5, 1) if args.tiny else (60, 3)
    robot = default_robot()
    with tempfile.TemporaryDirectory() as folder:
        bag = Path(folder) / "bag"
        messages = write_bag(bag, poses)
        alone_s, _ = median_time(lambda: read_alone(bag), repeats)
        twin_s, imported = median_time(lambda: import_files([bag], robot, angle_unit=None,
                                                            rule=StillRule()), repeats)
    print(f"bag: {messages} messages, {poses} stops; twin kept "
          f"{len(imported.measurements.q_rad)} poses")
    print(f"rosbags alone (read + deserialise): {messages / alone_s:,.0f} messages/s")
    print(f"twin import (that + poses):          {messages / twin_s:,.0f} messages/s "
          f"({twin_s / alone_s:.2f}× the time)")


if __name__ == "__main__":
    main()
