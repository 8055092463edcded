"""The 3D scene under ``world/``: robots in every measured pose, the encoder port, the cable.

Positions are logged in metres in the robot base frame (z up), one row per pose on the ``pose``
timeline; the link polylines are the frame origins 0..n of the core's FK
(:func:`twin.kinematics.chain`), so what is drawn is exactly what is fitted.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import rerun as rr
from numpy.typing import ArrayLike, NDArray

from twin.dataset import Measurements
from twin.kinematics import frames
from twin.robot import RobotModel
from twin.units import m_to_mm
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
    writer: Writer, port_m: ArrayLike, flange_m: ArrayLike, length_m: ArrayLike
) -> None:
    """The port (``world/port``) and, per pose, the cable from the port to a flange.

    Args:
        writer: Where to log.
        port_m: Encoder port in the base frame, shape (3,), m.
        flange_m: Flange centres the cable runs to, shape (m, 3), m.
        length_m: Measured cable lengths, shape (m,), m, shown as each cable's label in mm.
    """
    port_m = np.asarray(port_m, dtype=np.float64)
    flange_m = np.asarray(flange_m, dtype=np.float64)
    poses = np.arange(flange_m.shape[0])
    writer.once(entities.PORT, rr.Points3D(port_m[None], radii=PORT_RADIUS_M,
                                           colors=PORT_COLOR, labels="port"))
    strips = np.stack([np.broadcast_to(port_m, flange_m.shape), flange_m], axis=1)  # (m, 2, 3)
    writer.series(
        entities.CABLE, entities.POSE_TIMELINE, poses,
        rr.LineStrips3D.columns(
            strips=strips.astype(np.float32),
            colors=_colors(CABLE_COLOR, poses.size),
            radii=np.full(poses.size, CABLE_RADIUS_UI, dtype=np.float32),
            labels=[f"L = {v:.3f} mm" for v in m_to_mm(length_m)],
        ),
    )


def log_scene(
    writer: Writer,
    robots: Mapping[str, RobotModel],
    measurements: Measurements,
    port_m: ArrayLike,
    cable_to: str,
) -> None:
    """Robots, port and cable for every measured pose.

    Args:
        writer: Where to log.
        robots: Label to model, see :func:`log_robots`.
        measurements: The poses and measured lengths.
        port_m: Encoder port, shape (3,), m.
        cable_to: Label of the robot whose flange the cable is drawn to (the true one when
            known: that is where the physical cable went).
    """
    writer.once(entities.WORLD, rr.ViewCoordinates.RIGHT_HAND_Z_UP)
    log_robots(writer, robots, measurements.q_rad)
    flange_m = robots[cable_to].flange_positions(measurements.q_rad)
    log_port_and_cable(writer, port_m, flange_m, measurements.lengths)
