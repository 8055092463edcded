"""The 3D scene under ``world/``: robots in every measured pose, the encoder port, the cable.

Positions are logged in metres in the robot base frame (z up), one row per pose on the ``pose``
timeline; the link polylines are the frame origins 0..n of the core's FK
(:func:`twin.geometry.kinematics.chain`), so what is drawn is exactly what is fitted.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import rerun as rr
from numpy.typing import ArrayLike, NDArray

from twin.dataset import Measurements
from twin.geometry.kinematics import frames
from twin.report.display import POSITION_DECIMALS, mm, xyz_mm
from twin.rig import Rig
from twin.robot import RobotModel
from twin.viz import entities
from twin.viz.writer import Writer

NOMINAL_COLOR = (150, 150, 150)
TRUE_COLOR = (40, 170, 80)
METHOD_COLORS = ((230, 120, 20), (30, 120, 220), (200, 40, 160), (220, 200, 30), (20, 190, 190),
                 (140, 80, 220), (200, 60, 50), (110, 160, 40), (90, 90, 200), (160, 110, 60))
"""Identified models, in the order the methods ran."""
CABLE_COLOR = (240, 220, 60)
PORT_COLOR = (255, 80, 80)
LINK_RADIUS_UI = -4.0
"""Negative radii are in UI points: the links keep their width at any zoom."""
CABLE_RADIUS_UI = -1.0
PORT_RADIUS_M = 0.012

TOOL_OFFSET_M = 1e-9
"""A tool frame farther than this from the last joint frame gets its own polyline point, m."""


def robot_color(label: str, order: int = 0) -> tuple[int, int, int]:
    """Colour of a robot label: nominal grey, true green, identified by method order."""
    if label == "nominal":
        return NOMINAL_COLOR
    if label == "true":
        return TRUE_COLOR
    return METHOD_COLORS[order % len(METHOD_COLORS)]


def _colors(color: tuple[int, int, int], rows: int) -> NDArray[np.uint8]:
    """One RGB colour per row, shape (rows, 3)."""
    return np.tile(np.asarray(color, dtype=np.uint8), (rows, 1))


def log_robots(
    writer: Writer, robots: Mapping[str, RobotModel], q_rad: ArrayLike, first_order: int = 0
) -> None:
    """Each robot's links in every pose, ``world/robot/<label>``.

    Args:
        writer: Where to log.
        robots: Label (``nominal``, ``true``, ``identified/<method>``) to model; identified
            models are coloured in the order given.
        q_rad: Joint angles, shape (m, n), rad.
        first_order: Colour index of the first identified model (when logged one by one).
    """
    q_rad = np.asarray(q_rad, dtype=np.float64)
    poses = np.arange(q_rad.shape[0])
    identified = first_order
    for label, robot in robots.items():
        chain = frames(robot.structure, robot.dh, q_rad)
        origins = chain.origins  # (m, n+1, 3): one polyline per pose
        if np.linalg.norm(robot.structure.tool[:3, 3]) > TOOL_OFFSET_M:
            origins = np.concatenate([origins, chain.flange[..., None, :3, 3]], axis=-2)
        color = robot_color(label, identified)
        identified += label not in ("nominal", "true")
        writer.series(
            entities.robot(label), entities.POSE_TIMELINE, poses,
            rr.LineStrips3D.columns(
                strips=origins.astype(np.float32),
                colors=_colors(color, poses.size),
                radii=np.full(poses.size, LINK_RADIUS_UI, dtype=np.float32),
            ),
        )


def log_port_and_cable(
    writer: Writer, port_m: ArrayLike, flange_m: ArrayLike, length_m: ArrayLike,
    port_names: tuple[str, ...] = ("port",), port_index: ArrayLike | None = None,
) -> None:
    """The ports (``world/port``) and, per pose, the cable from its port to the measured point.

    Args:
        writer: Where to log.
        port_m: Encoder port(s) in the base frame, shape (3,) or (k, 3), m.
        flange_m: Points the cable runs to (flange or eyelet), shape (m, 3), m.
        length_m: Measured cable lengths, shape (m,), m, shown as each cable's label in mm.
        port_names: Each port's name, length k.
        port_index: Each pose's port, shape (m,); port 0 if None.
    """
    ports = np.asarray(port_m, dtype=np.float64).reshape(-1, 3)
    flange_m = np.asarray(flange_m, dtype=np.float64)
    poses = np.arange(flange_m.shape[0])
    index = np.zeros(poses.size, dtype=np.intp) if port_index is None \
        else np.asarray(port_index, dtype=np.intp)
    writer.once(entities.PORT, rr.Points3D(ports, radii=PORT_RADIUS_M, colors=PORT_COLOR,
                                           labels=list(port_names)))
    strips = np.stack([ports[index], flange_m], axis=1)  # (m, 2, 3)
    writer.series(
        entities.CABLE, entities.POSE_TIMELINE, poses,
        rr.LineStrips3D.columns(
            strips=strips.astype(np.float32),
            colors=_colors(CABLE_COLOR, poses.size),
            radii=np.full(poses.size, CABLE_RADIUS_UI, dtype=np.float32),
            labels=[f"L = {mm(v, POSITION_DECIMALS)}" for v in np.ravel(length_m)],
        ),
    )


def log_measured_points(writer: Writer, points_m: ArrayLike, labels: list[str]) -> None:
    """Per pose, the measured point (tracker target, ball) in the base frame,
    ``world/measured``.

    Args:
        writer: Where to log.
        points_m: The points, shape (m, 3), m.
        labels: A label per pose (the reading, or the fixed point's name).
    """
    points = np.asarray(points_m, dtype=np.float64)
    poses = np.arange(points.shape[0])
    writer.series(
        entities.MEASURED, entities.POSE_TIMELINE, poses,
        rr.Points3D.columns(positions=points.astype(np.float32),
                            colors=_colors(CABLE_COLOR, poses.size),
                            radii=np.full(poses.size, PORT_RADIUS_M / 2, dtype=np.float32),
                            labels=labels),
    )


def log_fixed_points(writer: Writer, points_m: ArrayLike, names: tuple[str, ...]) -> None:
    """The fixed points (identified or true), ``world/fixed_points``."""
    writer.once(entities.FIXED_POINTS, rr.Points3D(np.asarray(points_m, dtype=np.float64),
                                                   radii=PORT_RADIUS_M / 2, colors=PORT_COLOR,
                                                   labels=list(names)))


def log_measurement(writer: Writer, rig: Rig, measurements: Measurements,
                    points_m: ArrayLike) -> None:
    """What was measured at every pose: the cable from its port to the measured point, or the
    measured point itself (tracker positions, fixed points, with the fixed points).

    Args:
        writer: Where to log.
        rig: The rig (ports, fixed points).
        measurements: The poses and readings.
        points_m: Where the measured point is drawn at each pose, shape (m, 3), m.
    """
    if measurements.kind == "length":
        log_port_and_cable(writer, rig.ports_m, points_m, measurements.lengths,
                           rig.port_names, measurements.port_index)
        return
    if measurements.kind == "position":
        assert measurements.position_m is not None
        labels = [xyz_mm(position) for position in measurements.position_m]
    else:
        assert measurements.point is not None
        names = rig.point_names or measurements.point_names
        labels = [names[j] if j < len(names) else str(j) for j in measurements.point]
        if rig.point_names:
            log_fixed_points(writer, rig.points_m, rig.point_names)
    log_measured_points(writer, points_m, labels)


def log_scene(
    writer: Writer,
    robots: Mapping[str, RobotModel],
    measurements: Measurements,
    rig: Rig,
    cable_to: str,
) -> None:
    """Robots and what was measured (ports and cable, or measured points) for every pose.

    Args:
        writer: Where to log.
        robots: Label to model, see :func:`log_robots`.
        measurements: The poses and readings.
        rig: The rig (ports, the measured point in the flange frame, fixed points).
        cable_to: Label of the robot whose measured point the cable is drawn to (the true one
            when known: that is where the physical cable went).
    """
    writer.once(entities.WORLD, rr.ViewCoordinates.RIGHT_HAND_Z_UP)
    log_robots(writer, robots, measurements.q_rad)
    transforms = robots[cable_to].flange_transforms(measurements.q_rad)
    points_m = transforms[:, :3, :3] @ rig.attachment_m + transforms[:, :3, 3]
    log_measurement(writer, rig, measurements, points_m)
