"""The 3D scene under ``world/``: robots in every measured pose, and what was measured (the
encoder port and the cable, the measured points…: each measurement kind draws its own).

Positions are logged in metres in the robot base frame (z up), one row per pose on the ``pose``
timeline; the link polylines are the frame origins 0..n of the core's FK
(:func:`twin.geometry.kinematics.chain`), so what is drawn is exactly what is fitted.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import rerun as rr
from numpy.typing import ArrayLike, NDArray

from twin.arrays import Array
from twin.dataset import Measurements
from twin.geometry.kinematics import frames
from twin.kinds import KINDS
from twin.rig import Rig
from twin.robot import RobotModel
from twin.viz import entities
from twin.viz.writer import Writer

NOMINAL_COLOR = (150, 150, 150)
TRUE_COLOR = (40, 170, 80)
METHOD_COLORS = ((230, 120, 20), (30, 120, 220), (200, 40, 160), (220, 200, 30), (20, 190, 190),
                 (140, 80, 220), (200, 60, 50), (110, 160, 40), (90, 90, 200), (160, 110, 60))
"""Identified models, in the order the methods ran."""
READING_COLOR = (240, 220, 60)
"""What was measured at each pose: a cable, a measured point."""
ANCHOR_COLOR = (255, 80, 80)
"""The rig's fixed parts: ports, fixed points."""
LINK_RADIUS_UI = -4.0
"""Negative radii are in UI points: the links keep their width at any zoom."""
LINE_RADIUS_UI = -1.0

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


class SceneCanvas:
    """The Rerun scene as a measurement kind draws on it (:class:`twin.kinds.base.Canvas`):
    the rig's fixed parts once under ``world/<leaf>`` in red, a point or segment per pose on
    the pose timeline in yellow."""

    def __init__(self, writer: Writer) -> None:
        self.writer = writer

    def anchors(self, leaf: str, points_m: Array, labels: Sequence[str], radius_m: float
                ) -> None:
        """Fixed parts of the rig (ports, fixed points), logged once."""
        self.writer.once(entities.world(leaf),
                         rr.Points3D(np.asarray(points_m, dtype=np.float64).reshape(-1, 3),
                                     radii=radius_m, colors=ANCHOR_COLOR, labels=list(labels)))

    def marks(self, leaf: str, points_m: Array, labels: Sequence[str], radius_m: float) -> None:
        """A point per pose (a tracker target, a ball)."""
        points = np.asarray(points_m, dtype=np.float64)
        poses = np.arange(points.shape[0])
        self.writer.series(
            entities.world(leaf), entities.POSE_TIMELINE, poses,
            rr.Points3D.columns(positions=points.astype(np.float32),
                                colors=_colors(READING_COLOR, poses.size),
                                radii=np.full(poses.size, radius_m, dtype=np.float32),
                                labels=list(labels)),
        )

    def lines(self, leaf: str, starts_m: Array, ends_m: Array, labels: Sequence[str]) -> None:
        """A segment per pose (the cable from its port)."""
        strips = np.stack([np.asarray(starts_m, dtype=np.float64),
                           np.asarray(ends_m, dtype=np.float64)], axis=1)  # (m, 2, 3)
        poses = np.arange(strips.shape[0])
        self.writer.series(
            entities.world(leaf), entities.POSE_TIMELINE, poses,
            rr.LineStrips3D.columns(
                strips=strips.astype(np.float32),
                colors=_colors(READING_COLOR, poses.size),
                radii=np.full(poses.size, LINE_RADIUS_UI, dtype=np.float32),
                labels=list(labels),
            ),
        )


def log_measurement(writer: Writer, rig: Rig, measurements: Measurements,
                    points_m: ArrayLike) -> None:
    """What was measured at every pose, as the measurement kind draws it
    (:meth:`twin.kinds.base.Kind.draw`): the cable from its port to the measured point, or the
    measured point itself (tracker positions, fixed points, with the fixed points).

    Args:
        writer: Where to log.
        rig: The rig (ports, fixed points).
        measurements: The poses and readings.
        points_m: Where the measured point is drawn at each pose, shape (m, 3), m.
    """
    KINDS.lookup(measurements.kind).draw(SceneCanvas(writer), rig, measurements,
                                         np.asarray(points_m, dtype=np.float64))


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
