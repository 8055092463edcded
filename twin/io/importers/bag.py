"""ROS 1 and ROS 2 bags (SQLite or MCAP storage) into measurements, read with ``rosbags``
(the extra ``cabletwin[ros]``; no ROS install).

A bag holds ``sensor_msgs/JointState`` (the joints, rad, named as the robot's joints) and one
measurement topic: ``std_msgs/Float64`` a cable length (m), ``geometry_msgs/PointStamped`` a
tracker's point (m) or ``geometry_msgs/PoseStamped`` its position (m). Poses are cut where the
joints stood still (:func:`twin.io.importers.still.still_windows`); a pose's joints and its
reading are the medians over its window. Times are the bag's receive times, one clock for every
topic. Topics are found by type when a bag has one of each; else name them.

Every window or message left out is reported with the reason (no reading inside the window, a
joint missing from a message, a joint outside the robot's limits).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from twin.errors import InputError
from twin.io.importers.base import Imported, StillRule, outside_limits
from twin.io.importers.still import still_windows
from twin.kinds import KINDS, Kind
from twin.robot import RobotModel
from twin.units import m_to_mm

JOINT_STATE = "sensor_msgs/msg/JointState"
READINGS = {message: kind for kind in KINDS.values() for message in kind.messages}
"""Measurement message types and the kind each gives (:attr:`twin.kinds.base.Kind.messages`)."""
BAG_SUFFIXES = (".bag", ".db3", ".mcap")


def is_bag(path: Path) -> bool:
    """Whether a path is a bag: a ROS 1 ``.bag``, a ROS 2 bag folder (``metadata.yaml``) or
    one of its ``.db3``/``.mcap`` files."""
    return path.suffix in BAG_SUFFIXES or (path.is_dir() and (path / "metadata.yaml").exists())


def _bag_path(path: Path) -> Path:
    """What rosbags opens: a ROS 2 storage file's folder when it holds the metadata."""
    if path.suffix in (".db3", ".mcap") and (path.parent / "metadata.yaml").exists():
        return path.parent
    return path


def _topic(connections: Sequence[Any], wanted: str | None, types: Sequence[str], what: str,
           flag: str, source: Path) -> Any:
    """The one connection of a topic: the named one, or the only one of the types."""
    if wanted is not None:
        found = [c for c in connections if c.topic == wanted]
        if not found or found[0].msgtype not in types:
            raise InputError(f"topic {wanted!r}" + (f" of type {found[0].msgtype}" if found
                                                   else " not in the bag"),
                             f"a {what} topic ({', '.join(types)})", source=source, where=flag)
        return found[0]
    found = [c for c in connections if c.msgtype in types]
    topics = sorted({c.topic for c in found})
    if len(topics) != 1:
        listed = ", ".join(f"{c.topic} ({c.msgtype})" for c in connections) or "none"
        raise InputError(f"{len(topics)} {what} topics (topics: {listed})",
                         f"one, or its name with {flag}", source=source)
    return next(c for c in found if c.topic == topics[0])


def _reading(message: Any, msgtype: str) -> NDArray[np.float64]:
    if msgtype == "std_msgs/msg/Float64":
        return np.array([message.data])
    point = message.point if msgtype == "geometry_msgs/msg/PointStamped" \
        else message.pose.position
    return np.array([point.x, point.y, point.z])


def _joint_samples(reader: Any, connection: Any, names: Sequence[str], source: Path,
                   dropped: list[str]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Times (m,) s and joints (m, n) rad of the JointState messages that name every joint."""
    times, rows = [], []
    for _, stamp, raw in reader.messages(connections=[connection]):
        message = reader.deserialize(raw, connection.msgtype)
        index = {name: i for i, name in enumerate(message.name)}
        missing = [name for name in names if name not in index]
        if missing or len(message.position) < len(message.name):
            dropped.append(f"{source}: {connection.topic} at {stamp * 1e-9:.3f} s: no "
                           f"position of {', '.join(missing) or 'every named joint'}: dropped")
            continue
        times.append(stamp * 1e-9)
        rows.append([message.position[index[name]] for name in names])
    if not rows:
        raise InputError(f"no {connection.topic} message with the joints "
                         f"{', '.join(names)}", "JointState messages naming the robot's joints",
                         source=source)
    return np.array(times), np.array(rows, dtype=np.float64)


def read_bag(path: str | Path, robot: RobotModel, rule: StillRule, *,
             joints_topic: str | None = None, reading_topic: str | None = None) -> Imported:
    """The poses of a bag (see the module docstring).

    Raises:
        InputError: if the bag cannot be read, has no joints or reading topic to go by, or no
            pose survives.
    """
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    source = Path(path)
    dropped: list[str] = []
    try:
        reader_context = AnyReader([_bag_path(source)],
                                   default_typestore=get_typestore(Stores.ROS2_HUMBLE))
        reader = reader_context.__enter__()
    except Exception as exc:
        raise InputError(f"a file rosbags cannot open ({type(exc).__name__}: {exc})",
                         "a ROS 1 bag, or a ROS 2 bag folder (metadata.yaml) with its "
                         "SQLite or MCAP file", source=source) from None
    try:
        joints = _topic(reader.connections, joints_topic, (JOINT_STATE,), "joint state",
                        "--joints-topic", source)
        readings = _topic(reader.connections, reading_topic, tuple(READINGS), "reading",
                          "--reading-topic", source)
        t_s, q_rad = _joint_samples(reader, joints, robot.joint_names, source, dropped)
        stamps, values = [], []
        for _, stamp, raw in reader.messages(connections=[readings]):
            stamps.append(stamp * 1e-9)
            values.append(_reading(reader.deserialize(raw, readings.msgtype), readings.msgtype))
    finally:
        reader_context.__exit__(None, None, None)
    order = np.argsort(t_s, kind="stable")
    return _poses(source, robot, rule, t_s[order], q_rad[order], np.array(stamps),
                  np.array(values).reshape(len(values), -1), READINGS[readings.msgtype],
                  readings.topic, dropped)


def _poses(source: Path, robot: RobotModel, rule: StillRule, t_s: NDArray[np.float64],
           q_rad: NDArray[np.float64], stamps: NDArray[np.float64],
           values: NDArray[np.float64], kind: Kind, topic: str, dropped: list[str]) -> Imported:
    """One pose per still window that has readings and lies within the joint limits."""
    q_rows, readings = [], []
    for window in still_windows(t_s, q_rad, rule.tol_rad, rule.min_s):
        inside = (stamps >= window.start_s) & (stamps <= window.end_s)
        span = f"{source}: still {window.start_s:.3f}–{window.end_s:.3f} s"
        if not np.any(inside):
            dropped.append(f"{span}: no {topic} message inside: dropped")
            continue
        reason = outside_limits(window.q_rad, robot)
        if reason:
            dropped.append(f"{span}: {reason}: dropped")
            continue
        q_rows.append(window.q_rad)
        readings.append(np.median(values[inside], axis=0))
    if not q_rows:
        raise InputError(f"no pose (joints still for {rule.min_s:g} s within "
                         f"{np.rad2deg(rule.tol_rad):g} deg, with a {topic} reading)",
                         "at least one", source=source)
    read_mm = m_to_mm(np.array(readings))
    try:
        return Imported(kind.from_columns(
            np.array(q_rows), {column: read_mm[:, k] for k, column in enumerate(kind.columns)},
            {}, list(range(1, len(q_rows) + 1)), None), dropped)
    except InputError as exc:
        raise exc.at(source) from None
