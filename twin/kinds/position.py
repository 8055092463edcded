"""3-D positions from a laser tracker: the measured point, seen in the tracker's frame.

For pose i with the measured point at p_i in the base frame, three rows
``r_i = R_c (R_0 p_i + t_0) + t_c − y_i``: ``(R_0, t_0)`` the rig's
:attr:`~twin.rig.Rig.base_in_tracker`, ``(R_c, t_c)`` the correction of group ``base``
(:mod:`twin.unknowns.tracker`; none without it), y_i the tracker's reading.

Readings: ``position_m`` (m, 3), m, in the tracker's frame. In a file: ``x,y,z`` (mm).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import Array, frozen_array
from twin.dataset import Measurements
from twin.errors import InputError
from twin.geometry.rigid import angles, kabsch, rotation, rotation_derivatives
from twin.kinds.base import (
    MARK_RADIUS_M,
    Canvas,
    Kind,
    KindJacobian,
    Measured,
    UnitHint,
    mm_cells,
)
from twin.kinds.bench import (
    TARGET_KEYS,
    Bench,
    Captured,
    Fields,
    TargetSetup,
    read_target,
    refuse_port,
)
from twin.report.display import AS_GIVEN, mm, xyz_mm
from twin.rig import Rig
from twin.units import MAX_LENGTH_M, m_to_mm, mm_to_m, rad_to_deg

if TYPE_CHECKING:
    from twin.model import Model

POSITION = "position_m"
"""The readings: the measured point in the instrument's frame, shape (m, 3), m."""
COLUMNS = ("x", "y", "z")
"""The file columns of a position, mm."""


def position_measurements(q_rad: ArrayLike, position_m: ArrayLike, *,
                          approach: ArrayLike | None = None) -> Measurements:
    """Tracker positions: joint angles (m, n), rad, and the measured point in the tracker's
    frame (m, 3), m (approach as :func:`twin.kinds.length.length_measurements`)."""
    return Measurements(np.asarray(q_rad, dtype=np.float64), Position.name,
                        {POSITION: np.asarray(position_m, dtype=np.float64)},
                        approach=None if approach is None else np.asarray(approach))


def in_instrument(positions: Array, values: Mapping[str, Array], rig: Rig) -> Array:
    """Base-frame points (..., m, 3) in the instrument's frame: the rig's
    ``base_in_tracker`` and the correction of group ``base`` if estimated, shape (..., m, 3),
    m."""
    nominal = rig.base_in_tracker
    seen = positions @ nominal[:3, :3].T + nominal[:3, 3]
    if "base" not in values:
        return np.asarray(seen, dtype=np.float64)
    correction = values["base"]
    turned = np.einsum("...ij,...mj->...mi", rotation(correction[..., 3:]), seen)
    return np.asarray(turned + correction[..., None, :3], dtype=np.float64)


def frame_jacobian(positions: Array, values: Mapping[str, Array], rig: Rig
                   ) -> tuple[Array, Array | None]:
    """How a point seen in the instrument's frame moves: ∂/∂p = R_c R_0 (3, 3), and, with
    group ``base``, ∂/∂(t_c, rx, ry, rz) at each point (m, 3, 6) (None without it)."""
    nominal = rig.base_in_tracker
    turn = nominal[:3, :3]
    if "base" not in values:
        return turn, None
    angles = values["base"][3:]
    seen = positions @ nominal[:3, :3].T + nominal[:3, 3]
    columns = np.zeros((len(positions), 3, 6))
    columns[:, :, :3] = np.eye(3)
    columns[:, :, 3:] = np.einsum("kij,mj->mik", rotation_derivatives(angles), seen)
    return rotation(angles) @ turn, columns


def fit_frame(model: Model, data: Measurements, readings_m: Array) -> Model:
    """The model with the instrument's frame at the rigid fit (Kabsch) of the nominal model's
    measured points onto the readings (m, 3), m."""
    nominal = replace(model, rig=replace(model.rig, base_in_tracker=np.eye(4)))
    positions = nominal.positions(np.zeros(model.n_params), data)
    fit = kabsch(positions, readings_m)
    return replace(model, rig=replace(model.rig, base_in_tracker=fit.transform))


def read_xyz_mm(numbers: Mapping[str, Array], lines: Sequence[int]) -> Array:
    """The ``x,y,z`` columns, mm, each within ±:data:`~twin.units.MAX_LENGTH_M`, to m (m, 3).

    Raises:
        InputError: naming the line of a coordinate out of range.
    """
    xyz_mm_ = np.stack([numbers[c] for c in COLUMNS], axis=1)
    longest_mm = float(m_to_mm(MAX_LENGTH_M))
    bad = np.flatnonzero(np.any(np.abs(xyz_mm_) > longest_mm, axis=1))
    if bad.size:
        raise InputError(f"{np.max(np.abs(xyz_mm_[bad[0]])):g} mm",
                         f"coordinates within ±{longest_mm:g} mm", where=f"line {lines[bad[0]]}")
    return np.asarray(mm_to_m(xyz_mm_), dtype=np.float64)


COORDINATES_IN_METRES_MM = 10.0
"""Tracker coordinates all within ±this, mm, look like metres: an arm's workspace spans
hundreds of millimetres in any frame."""


def coordinates_hint(data: Measurements) -> UnitHint | None:
    """Tracker coordinates all within ±10 mm: given in metres, likely (the positions' and the
    6-D poses' hint, :meth:`twin.kinds.base.Kind.unit_hint`)."""
    read_m = data.value(POSITION)
    largest_m = float(np.max(np.abs(read_m))) if read_m.size else np.inf
    if largest_m >= mm_to_m(COORDINATES_IN_METRES_MM):
        return None
    read = mm(largest_m, significant=AS_GIVEN, unit=False)
    return UnitHint(True, "the tracker coordinates x, y, z are read in mm, and every one is "
                    f"within ±{COORDINATES_IN_METRES_MM:g} mm (the largest {read} mm) — they "
                    "look like metres; convert the file with `twin import --length-unit m`")


class Position(Kind):
    """Tracker positions (:mod:`twin.kinds.position`)."""

    name = "position"
    what = "tracker positions"
    rows_per_pose = 3
    groups = ("base",)
    columns = COLUMNS
    columns_text = "x,y,z (mm)"
    messages = ("geometry_msgs/msg/PointStamped", "geometry_msgs/msg/PoseStamped")
    in_instrument_frame = True
    measurement_keys = TARGET_KEYS

    def unit_hint(self, rig: Rig, data: Measurements) -> UnitHint | None:
        """Coordinates all within ±10 mm (:func:`coordinates_hint`)."""
        return coordinates_hint(data)

    def template(self, q_rad: Array, rig: Rig, labels: Mapping[str, NDArray[np.intp]]
                 ) -> Measurements:
        """Zero positions."""
        return position_measurements(q_rad, np.zeros((len(q_rad), 3)))

    def residuals(self, at: Measured, values: Mapping[str, Array], data: Measurements,
                  rig: Rig) -> Array:
        """r = tracker point − reading, shape (..., 3m), m: x, y, z of pose 1, then pose 2…"""
        difference = in_instrument(at.position_m, values, rig) - data.value(POSITION)
        return np.asarray(difference.reshape(*difference.shape[:-2], -1), dtype=np.float64)

    def measure(self, at: Measured, values: Mapping[str, Array], template: Measurements,
                rig: Rig) -> Measurements:
        """The tracker readings the model gives."""
        return Measurements(template.q_rad, self.name,
                            {POSITION: in_instrument(at.position_m, values, rig)},
                            approach=template.approach)

    def jacobian(self, at: Measured, values: Mapping[str, Array], data: Measurements,
                 rig: Rig) -> KindJacobian:
        """∂r/∂p = R_c R_0 at every pose; ∂r/∂t_c = I; ∂r/∂(rx, ry, rz) = ∂R_c/∂a (R_0 p + t_0).
        """
        m = len(data)
        turn, frame = frame_jacobian(at.position_m, values, rig)
        by_group = {} if frame is None else {"base": frame.reshape(3 * m, 6)}
        return KindJacobian(self.residuals(at, values, data, rig),
                            np.broadcast_to(turn, (m, 3, 3)).copy(), by_group)

    def start(self, model: Model, train: Measurements) -> Model:
        """With the tracker frame estimated: its rigid fit to the training readings."""
        return self.align(model, train) if model.has("base") else model

    def align(self, model: Model, data: Measurements) -> Model:
        """The tracker frame at the rigid fit of the nominal model's points to the readings."""
        return fit_frame(model, data, data.value(POSITION))

    def units_ratio(self, data: Measurements, nominal: Array) -> float | None:
        """The readings' RMS spread about their mean over the nominal model's."""
        measured = data.value(POSITION)
        modelled_points = nominal[: 3 * len(data)].reshape(-1, 3) + measured
        read = np.sqrt(np.mean(np.sum((measured - measured.mean(axis=0)) ** 2, axis=1)))
        modelled = np.sqrt(np.mean(np.sum((modelled_points - modelled_points.mean(axis=0)) ** 2,
                                          axis=1)))
        return float(read / modelled) if modelled > 0 else np.inf

    def predict(self, model: Model, x: Array, poses: Measurements) -> dict[str, Array]:
        """The point in the tracker frame (what the tracker reads)."""
        return {POSITION: model.read(x, poses).value(POSITION)}

    def from_columns(self, q_rad: Array, numbers: Mapping[str, Array],
                     labels: Mapping[str, list[str]], lines: Sequence[int],
                     approach: NDArray[np.int8] | None) -> Measurements:
        """``x,y,z`` in mm, each within ±:data:`~twin.units.MAX_LENGTH_M`."""
        return position_measurements(q_rad, read_xyz_mm(numbers, lines), approach=approach)

    def to_columns(self, data: Measurements) -> list[tuple[str, list[str]]]:
        """``x,y,z`` (mm)."""
        xyz = m_to_mm(data.value(POSITION))
        return [(name, mm_cells(xyz[:, k])) for k, name in enumerate(COLUMNS)]

    prediction_note = " (mm, tracker frame)"

    def prediction_columns(self, predicted: Mapping[str, Array]) -> list[tuple[str, Array]]:
        """``tracker_x,tracker_y,tracker_z`` (mm, tracker frame)."""
        xyz = m_to_mm(predicted[POSITION])
        return [(f"tracker_{name}", xyz[:, k]) for k, name in enumerate(COLUMNS)]

    def describe(self, rig: Rig, data: Measurements) -> str:
        """``laser-tracker positions``."""
        return "laser-tracker positions"

    def read_setup(self, tables: Mapping[str, Fields]) -> TrackerSetup:
        """``[measurement]``: the target, the tracker's noise and pose; no ``[cable]``,
        ``[fixture]`` or ``[port]``."""
        target = read_target(tables, self.name, frame=True)
        refuse_port(tables, self.name)
        return TrackerSetup(target.attachment_m, target.attachment_told_m, target.sigma_m,
                            target.frame)

    def draw(self, canvas: Canvas, rig: Rig, data: Measurements, points_m: Array) -> None:
        """Per pose, the measured point labelled with its reading."""
        canvas.marks("measured", points_m,
                     [xyz_mm(position) for position in data.value(POSITION)], MARK_RADIUS_M)


def tracker_readings(points_m: Array, base_in_tracker: Array, sigma_m: Array,
                     rng: np.random.Generator) -> Array:
    """Tracker readings of base-frame points (m, 3): the tracker frame plus N(0, σ²) per axis,
    shape (m, 3), m."""
    seen = points_m @ base_in_tracker[:3, :3].T + base_in_tracker[:3, 3]
    return np.asarray(seen + rng.normal(0.0, 1.0, seen.shape) * sigma_m, dtype=np.float64)


@dataclass(frozen=True)
class TrackerSetup(TargetSetup):
    """A laser tracker in the twin (:class:`twin.kinds.bench.Setup`): the measured point at
    rest, carried into the tracker's frame by the true ``base_in_tracker`` and read with
    Gaussian noise of σ per axis (:func:`tracker_readings`).

    Attributes:
        attachment_m: The true target in the flange frame, shape (3,), m.
        attachment_told_m: The target the calibration is told, shape (3,), m.
        sigma_m: Noise 1σ per axis of a reading, shape (3,), m.
        base_in_tracker: The true tracker frame: where the base sits in it, shape (4, 4), m.
    """

    base_in_tracker: Array

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "base_in_tracker",
                           frozen_array(self.base_in_tracker, (4, 4), "base_in_tracker"))

    def rigs(self, rng: np.random.Generator) -> tuple[Rig, Rig]:
        """The true tracker frame; the calibration is told the target alone (the frame it
        starts at a rigid fit)."""
        return (Rig(attachment_m=self.attachment_m, base_in_tracker=self.base_in_tracker),
                Rig(attachment_m=self.attachment_told_m))

    def capture(self, bench: Bench, rig: Rig, rng: np.random.Generator) -> Captured:
        """The target at rest at drawn poses, read in the tracker frame with noise."""
        visit = bench.visit([None], rng)
        readings = tracker_readings(visit.rest.point_m, rig.base_in_tracker, self.sigma_m, rng)
        data = position_measurements(visit.q_rad, readings,
                                     approach=visit.approach)
        return Captured(data, visit.rest, np.zeros(0, dtype=np.intp), visit.joint_sigma_rad)

    def truth(self, rig: Rig) -> dict[str, Any]:
        """``tracker_pose``: the true frame, [x, y, z] mm and [rx, ry, rz] degrees."""
        tracker = rig.base_in_tracker
        return {"tracker_pose": [*m_to_mm(tracker[:3, 3]).tolist(),
                                 *rad_to_deg(angles(tracker[:3, :3])).tolist()]}
