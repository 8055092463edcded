"""Cable lengths: the drawstring encoder reads the distance from its port to the measured point.

For a row whose cable runs from port P_j, ``r = (1 + s) · ‖p − (P_j + δP_j)‖ + c − L`` (paper
eq. 1 with the optional port correction δP of group ``port``, length offset c of group
``offset`` — with capture sessions, the c of the row's session — and encoder scale s of group
``scale``). The scale multiplies the modelled distance, not the reading: the residual stays
reading minus model, in the reading's units, so that its noise is the encoder's σ whatever s is
(dividing the reading by 1 + s would scale the noise with it); the encoder's zero c is counted
in the reading's units, after the gain.

Readings: ``length_m`` (m,), m, and, when the encoder was moved between ports, the labels
``port`` naming each row's port. In a file: a ``length`` column (mm) and an optional ``port``
column; any kind's file may name each row's capture ``session`` (:data:`SESSION`), which gives
cable lengths one encoder zero per session.

A port nobody measured (``--port unknown``: :attr:`twin.rig.Rig.unknown_ports`) is started by
multilateration (:mod:`twin.geometry.multilateration`) from the nominal model's measured
points and the training lengths of its rows, the sessions' zeros estimated with it when the
offset is.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import Array, frozen_array, lengths
from twin.dataset import Labels, Measurements
from twin.errors import InputError
from twin.geometry.kinematics import Structure, distances, point_position
from twin.geometry.multilateration import multilaterate
from twin.kinds.base import (
    ANCHOR_RADIUS_M,
    Canvas,
    Kind,
    KindJacobian,
    Measured,
    Noise,
    Ranges,
    UnitHint,
    mm_cells,
)
from twin.kinds.bench import Bench, Captured, Fields
from twin.report.display import AS_GIVEN, POSITION_DECIMALS, mm, xyz_mm
from twin.rig import PORT_LABELS, SESSION_LABELS, Rig
from twin.robot import RobotModel
from twin.units import MAX_LENGTH_M, m_to_mm, mm_to_m

if TYPE_CHECKING:
    from twin.model import Model

LENGTH = "length_m"
"""The readings: cable lengths, shape (m,), m."""
PORT = PORT_LABELS
"""The labels of each row's port (absent with one port)."""
SESSION = SESSION_LABELS
"""The labels of each row's capture session (absent with one session)."""
COLUMN = "length"
"""The file column of a length, mm."""
PORT_IN_METRES_MM = 5.0
"""Ports within ±5 mm in every coordinate beside lengths of hundreds of mm look like metres."""
LENGTHS_IN_METRES_MM = 10.0
"""Cable lengths all positive and below this, mm, look like metres: a drawstring reads tens of
millimetres at the least, and an arm's cell in metres reads about 1."""


def cable_length(structure: Structure, dh: ArrayLike, q_rad: ArrayLike, port_m: ArrayLike,
                 point_m: ArrayLike | None = None) -> Array:
    """Straight-line cable length from the port to a point on the flange.

    Args:
        structure: What the table means.
        dh: Parameter tables, shape (..., 4, n), m and rad.
        q_rad: Joint angles, shape (m, n), rad.
        port_m: Port position in the base frame, shape (3,) or (..., m, 3), m.
        point_m: The cable's attachment in the flange frame, shape (3,), m; the flange centre
            if None.

    Returns:
        Lengths, shape (..., m), m.
    """
    positions = point_position(structure, dh, q_rad, point_m)
    return lengths(positions - np.asarray(port_m, dtype=np.float64))


def length_measurements(q_rad: ArrayLike, length_m: ArrayLike, *,
                        port: ArrayLike | None = None, port_names: Sequence[str] = (),
                        approach: ArrayLike | None = None) -> Measurements:
    """Cable lengths: joint angles (m, n), rad, and lengths (m,), m.

    Args:
        q_rad: Recorded joint angles, shape (m, n), rad.
        length_m: Cable lengths, shape (m,), m.
        port: Index of the port each row's cable ran from, shape (m,); None: one port.
        port_names: The name of each port index, when the data name their ports (a ``port``
            column); the calibration matches them to the rig's ports by name.
        approach: Direction each joint last moved in before the reading, shape (m, n), ±1.
    """
    labels = {} if port is None else {PORT: Labels(tuple(port_names),
                                                   np.asarray(port, dtype=np.intp))}
    if port is None and port_names:
        raise ValueError("port_names: names without the port indices")
    return Measurements(np.asarray(q_rad, dtype=np.float64), Length.name,
                        {LENGTH: np.asarray(length_m, dtype=np.float64)}, labels,
                        None if approach is None else np.asarray(approach))


def match_ports(measurements: Measurements, rig: Rig) -> Measurements:
    """The measurements with each row's port as an index into the rig's ports.

    Data that name their ports (a ``port`` column) are matched to the rig's ports by name;
    unnamed data use the rig's ports in order.

    Raises:
        InputError: for a port the rig does not have, or data from several unnamed ports.
    """
    names = measurements.names(PORT)
    index = measurements.index(PORT)
    if names:
        unknown = [name for name in names if name not in rig.port_names]
        if unknown:
            raise InputError(f"port {unknown[0]!r} in the measurements",
                             "one of the rig's ports: " + ", ".join(rig.port_names))
        matched = np.array([rig.port_names.index(name) for name in names])
        return Measurements(measurements.q_rad, measurements.kind, measurements.values,
                            {**measurements.labels, PORT: Labels(rig.port_names,
                                                                 matched[index])},
                            measurements.approach)
    if int(index.max()) >= len(rig.ports_m):
        raise InputError(f"{int(index.max()) + 1} ports in the measurements",
                         f"at most the rig's {len(rig.ports_m)}")
    return measurements


def match_sessions(measurements: Measurements, rig: Rig) -> tuple[Rig, Measurements]:
    """The rig with the data's capture sessions (when it has none yet) and the data with each
    row's session as an index into the rig's.

    Raises:
        InputError: for a session the rig (its training data) does not have.
    """
    names = measurements.names(SESSION)
    if not names:
        return rig, measurements
    if not rig.sessions:
        return replace(rig, sessions=names), measurements
    unknown = [name for name in names if name not in rig.sessions]
    if unknown:
        raise InputError(f"session {unknown[0]!r} in the measurements",
                         "one of the training data's sessions: " + ", ".join(rig.sessions))
    matched = np.array([rig.sessions.index(name) for name in names])
    return rig, Measurements(measurements.q_rad, measurements.kind, measurements.values,
                             {**measurements.labels, SESSION: Labels(
                                 rig.sessions, matched[measurements.index(SESSION)])},
                             measurements.approach)


def start_ports(model: Model, train: Measurements) -> Model:
    """The model with each port nobody measured at the point its training rows' lengths
    place it, from the nominal model's measured points (multilateration; the sessions' zeros
    found with it when the offset is estimated).

    Raises:
        InputError: when the port is not estimated, or its rows' points are too few or lie on
            one plane (the port's mirror image through it fits as well).
    """
    rig = model.rig
    if not rig.unknown_ports:
        return model
    if not model.has("port"):
        raise InputError(f"the port {rig.unknown_ports[0]!r} unknown without --estimate-port",
                         "--estimate-port: a port nobody measured is found from the data")
    points = point_position(model.robot.structure, model.robot.dh, train.q_rad,
                            rig.attachment_m)
    ports = np.array(rig.ports_m)
    for name in rig.unknown_ports:
        j = rig.port_names.index(name)
        rows = train.index(PORT) == j
        needed = 4 + (len(rig.sessions) or 1) * model.has("offset")
        found = multilaterate(points[rows], train.value(LENGTH)[rows],
                              offsets=train.index(SESSION)[rows] if model.has("offset")
                              else None) if rows.sum() >= needed + 1 else None
        if found is None or not found.determined:
            raise InputError(f"{int(rows.sum())} training poses from the port {name!r}"
                             + ("" if found is None else " whose measured points lie on "
                                "one plane"), f"at least {needed + 1} poses whose measured "
                             "points span 3-D (not on one plane) to find a port nobody "
                             "measured (or its position as --port)")
        ports[j] = found.point_m
    return replace(model, rig=replace(rig, ports_m=ports))


def _sessions(offsets: Array, data: Measurements) -> NDArray[np.intp]:
    """Each row's index into the offsets (..., s): its session's, or the one offset of a model
    fitted without sessions."""
    return data.index(SESSION) if offsets.shape[-1] > 1 else np.zeros(len(data), dtype=np.intp)


class Length(Kind):
    """Cable lengths (:mod:`twin.kinds.length`)."""

    name = "length"
    what = "cable lengths"
    rows_per_pose = 1
    groups = ("port", "offset", "scale")
    columns = (COLUMN,)
    optional_labels = (PORT,)
    columns_text = "length (mm)"
    messages = ("std_msgs/msg/Float64",)
    flags = (("--port", "cable lengths (a port per reading)"),)
    reading_noun = "lengths"
    on_flange = True
    encoder_keys = ("offset_mm", "scale_ppm")

    @staticmethod
    def _ports(values: Mapping[str, Array], data: Measurements, rig: Rig) -> Array:
        """The port of every row, shape (..., m, 3), m."""
        ports = rig.ports_m
        if "port" in values:
            correction = values["port"]
            estimated = rig.estimated_port_index
            full = np.zeros((*correction.shape[:-1], len(rig.ports_m), 3))
            full[..., estimated, :] = correction.reshape(*correction.shape[:-1], len(estimated),
                                                         3)
            ports = ports + full
        return np.asarray(ports[..., data.index(PORT), :], dtype=np.float64)

    def template(self, q_rad: Array, rig: Rig, labels: Mapping[str, NDArray[np.intp]]
                 ) -> Measurements:
        """Zero lengths, each row from its port (port 0 if not given)."""
        return length_measurements(q_rad, np.zeros(len(q_rad)), port=labels.get(PORT))

    def residuals(self, at: Measured, values: Mapping[str, Array], data: Measurements,
                  rig: Rig) -> Array:
        """r = (1 + scale) · ‖p − port‖ + offset − L, shape (..., m), m."""
        return self._from_distances(distances(at.position_m, self._ports(values, data, rig)),
                                    values, data)

    def ranges(self, values: Mapping[str, Array], data: Measurements, rig: Rig) -> Ranges:
        """Each row's port, shape (m, 3) or (..., m, 3) with an estimated port, m; the
        residuals from the distances to them; the readings, when neither a scale nor an offset
        is estimated."""
        plain = "scale" not in values and "offset" not in values
        return Ranges(self._ports(values, data, rig),
                      lambda distance_m: self._from_distances(distance_m, values, data),
                      data.value(LENGTH) if plain else None)

    @staticmethod
    def _from_distances(distance_m: Array, values: Mapping[str, Array], data: Measurements
                        ) -> Array:
        """r = (1 + scale) · ‖p − port‖ + offset − L from ‖p − port‖ (..., m), m."""
        length = distance_m
        if "scale" in values:
            length = length * (1.0 + values["scale"][..., :1])
        if "offset" in values:
            length = length + values["offset"][..., _sessions(values["offset"], data)]
        return np.asarray(length - data.value(LENGTH), dtype=np.float64)

    def measure(self, at: Measured, values: Mapping[str, Array], template: Measurements,
                rig: Rig) -> Measurements:
        """The cable lengths the model gives, each row from its port."""
        lengths = self.residuals(at, values, template, rig) + template.value(LENGTH)
        return Measurements(template.q_rad, self.name, {LENGTH: lengths}, template.labels,
                            template.approach)

    def jacobian(self, at: Measured, values: Mapping[str, Array], data: Measurements,
                 rig: Rig) -> KindJacobian:
        """∂r/∂p = (1 + s) u, u the unit vector from the port to the point; ∂r/∂δP_j = −(1 + s) u
        on the rows of estimated port j; ∂r/∂s = ‖p − port‖; ∂r/∂c = 1."""
        difference = at.position_m - self._ports(values, data, rig)
        distance = lengths(difference)
        u = difference / distance[:, None]
        by_group: dict[str, Array] = {}
        if "scale" in values:
            by_group["scale"] = distance[:, None]
            gain = 1.0 + values["scale"][0]
            distance, u = gain * distance, gain * u
        if "port" in values:
            columns = np.zeros((len(data), len(rig.ports_m), 3))
            columns[np.arange(len(data)), data.index(PORT)] = -u
            by_group["port"] = columns[:, rig.estimated_port_index].reshape(len(data), -1)
        if "offset" in values:
            session = _sessions(values["offset"], data)
            distance = distance + values["offset"][session]
            by_group["offset"] = np.eye(len(values["offset"]))[session]
        return KindJacobian(distance - data.value(LENGTH), u[:, None, :], by_group)

    def pivot(self, rig: Rig) -> Array | None:
        """The first port: one cable cannot see the arm turned about the vertical through it
        on a chain that carries its arm sideways."""
        return rig.ports_m[0] if len(rig.ports_m) else None

    def prepare(self, robot: RobotModel, rig: Rig, data: Measurements, noise: Noise
                ) -> tuple[Rig, Measurements]:
        """The rows' ports matched to the rig's (:func:`match_ports`), their sessions too
        (:func:`match_sessions`).

        Raises:
            InputError: without a port, or for a port or session the rig does not have.
        """
        if not len(rig.ports_m):
            raise InputError("no --port", "the encoder port as --port X,Y,Z in mm (or "
                             "NAME=X,Y,Z per port, --port unknown to find it from the data, "
                             "or a capture.toml as INPUT)")
        return match_sessions(match_ports(data, rig), rig)

    def implied_by(self, rig: Rig) -> tuple[str, ...]:
        """The sessions' encoder zeros (group ``offset``) when the data have several sessions:
        a re-hooked cable or a re-zeroed encoder shifts every length after it."""
        return ("offset",) if len(rig.sessions) > 1 else ()

    def start(self, model: Model, train: Measurements) -> Model:
        """Ports nobody measured started from the training lengths (:func:`start_ports`)."""
        return start_ports(model, train)

    def units_ratio(self, data: Measurements, nominal: Array) -> float | None:
        """The median reading over the nominal model's median length."""
        lengths = data.value(LENGTH)
        modelled = np.median(nominal[: len(data)] + lengths)
        return float(np.median(lengths) / modelled) if modelled > 0 else np.inf

    def unit_hint(self, rig: Rig, data: Measurements) -> UnitHint | None:
        """Cable lengths all of a few millimetres (metres, likely), or ports within ±5 mm beside
        lengths of hundreds of mm (the ports in metres, likely)."""
        if not len(data):
            return None
        read_m = data.value(LENGTH)
        median_m = float(np.median(read_m))
        # All of them: an encoder zeroed at some pose reads a few mm around it, and more away.
        if np.all(read_m > 0) and np.max(read_m) < mm_to_m(LENGTHS_IN_METRES_MM):
            read = mm(median_m, significant=AS_GIVEN, unit=False)
            return UnitHint(True, "the cable lengths are read in mm, and every one is below "
                            f"{LENGTHS_IN_METRES_MM:g} mm (median {read} mm) — they look like "
                            f"metres ({read} m); convert the file with "
                            "`twin import --length-unit m`")
        told = [j for j, name in enumerate(rig.port_names) if name not in rig.unknown_ports]
        if not told:
            return None
        small = np.all(np.abs(m_to_mm(rig.ports_m[told])) <= PORT_IN_METRES_MM)
        if small and median_m > 20 * float(mm_to_m(PORT_IN_METRES_MM)):
            return UnitHint(False, f"every port coordinate is within ±{PORT_IN_METRES_MM:g} mm "
                            "while the cable lengths are hundreds of millimetres: the port is "
                            "read in mm — it looks like metres (0.6 for 600 mm)")
        return None

    def predict(self, model: Model, x: Array, poses: Measurements) -> dict[str, Array]:
        """The cable length, when the rig has one port."""
        if len(model.rig.ports_m) != 1:
            return {}
        return {LENGTH: model.read(x, poses).value(LENGTH)}

    def from_columns(self, q_rad: Array, numbers: Mapping[str, Array],
                     labels: Mapping[str, list[str]], lines: Sequence[int],
                     approach: NDArray[np.int8] | None) -> Measurements:
        """A positive ``length`` in mm, at most :data:`~twin.units.MAX_LENGTH_M`; the
        ``port`` names, if given."""
        length_mm = numbers[COLUMN]
        longest_mm = float(m_to_mm(MAX_LENGTH_M))
        bad = np.flatnonzero((length_mm <= 0) | (length_mm > longest_mm))
        if bad.size:
            raise InputError(f"{length_mm[bad[0]]:g} mm",
                             f"a positive cable length in mm, at most {longest_mm:g}",
                             where=f"line {lines[bad[0]]}, column {COLUMN}")
        ports = Labels.of(labels[PORT]) if PORT in labels else None
        return length_measurements(q_rad, mm_to_m(length_mm),
                                   port=None if ports is None else ports.indices,
                                   port_names=() if ports is None else ports.names,
                                   approach=approach)

    def to_columns(self, data: Measurements) -> list[tuple[str, list[str]]]:
        """``length`` (mm) and, for several ports, ``port``."""
        columns = [(COLUMN, mm_cells(m_to_mm(data.value(LENGTH))))]
        if PORT in data.labels:
            columns.append((PORT, data.labels[PORT].per_row("port")))
        return columns

    def prediction_columns(self, predicted: Mapping[str, Array]) -> list[tuple[str, Array]]:
        """``length`` (mm)."""
        return [(COLUMN, m_to_mm(predicted[LENGTH]))] if LENGTH in predicted else []

    def describe(self, rig: Rig, data: Measurements) -> str:
        """``port (600.000, -400.000, 100.000) mm`` or ``2 ports (front, left)``, the ports
        nobody measured said (``, port front unknown: started from the data``), the sessions
        counted."""
        text = f"port {xyz_mm(rig.ports_m[0])}" if len(rig.ports_m) == 1 \
            else f"{len(rig.ports_m)} ports ({', '.join(rig.port_names)})"
        if rig.unknown_ports:
            named = "the port" if rig.unknown_ports == ("port",) \
                else "port " + ", ".join(rig.unknown_ports)
            text += f", {named} unknown: started from the data (multilateration)"
        return text + (f", {len(rig.sessions)} sessions (an encoder zero each)"
                       if len(rig.sessions) > 1 else "")

    def summary(self, data: Measurements) -> str:
        """``, cable lengths 512.300 … 1203.400 mm``."""
        lengths = data.value(LENGTH)
        return (f", cable lengths {mm(lengths.min(), POSITION_DECIMALS, unit=False)} … "
                f"{mm(lengths.max(), POSITION_DECIMALS)}")

    def read_setup(self, tables: Mapping[str, Fields]) -> CableSetup:
        """The encoder's ports and eyelet (:func:`read_cable`)."""
        return read_cable(tables)

    def deviation(self, rest: Any, rigid_m: Array, rig: Rig, data: Measurements) -> Array:
        """The true length minus the rigid model's, per row, m."""
        ports = rig.ports_m[data.index(PORT)]
        return np.asarray(rest.length_m - np.linalg.norm(rigid_m - ports, axis=1),
                          dtype=np.float64)

    def draw(self, canvas: Canvas, rig: Rig, data: Measurements, points_m: Array) -> None:
        """The ports (``world/port``) and, per pose, the cable from its port to the measured
        point, labelled with the reading."""
        canvas.anchors("port", rig.ports_m, list(rig.port_names), ANCHOR_RADIUS_M)
        canvas.lines("cable", rig.ports_m[data.index(PORT)], points_m,
                     [f"L = {mm(v, POSITION_DECIMALS)}" for v in data.value(LENGTH)])


@dataclass(frozen=True)
class CableSetup:
    """A drawstring encoder in the twin: one cable from one port, or moved between stations
    (:class:`twin.kinds.bench.Setup`).

    Attributes:
        attachment_m: The true cable eyelet in the flange frame, shape (3,), m.
        attachment_told_m: The eyelet the calibration is told, shape (3,), m.
        station_names: The name of each port, length k (``port`` for the one port).
        stations_m: The true ports, base frame, shape (k, 3), m.
        port_told_m: The one port the calibration is told, shape (3,), m; None: each true
            port plus an N(0, ``port_error_m``²) draw per axis.
        port_error_m: 1σ per axis of a told port's error, m.
    """

    attachment_m: Array
    attachment_told_m: Array
    station_names: tuple[str, ...]
    stations_m: Array
    port_told_m: Array | None = None
    port_error_m: float = 0.0

    def __post_init__(self) -> None:
        for name in ("attachment_m", "attachment_told_m"):
            object.__setattr__(self, name, frozen_array(getattr(self, name), (3,), name))
        stations = np.asarray(self.stations_m, dtype=np.float64).reshape(-1, 3)
        if not len(stations):
            raise ValueError("port_m: cable lengths need a port")
        object.__setattr__(self, "stations_m", frozen_array(stations, stations.shape,
                                                            "stations_m"))
        if len(self.station_names) != len(stations):
            raise ValueError("station_names: one name per station expected")
        if self.port_told_m is not None:
            object.__setattr__(self, "port_told_m",
                               frozen_array(self.port_told_m, (3,), "port_told_m"))

    @property
    def ports_m(self) -> Array:
        """The true ports, shape (k, 3), m: a cable from each."""
        return self.stations_m

    @property
    def pose_count(self) -> int | None:
        """None: the scenario's ``[poses]`` set them."""
        return None

    def instrument_sigma_m(self, encoder_sigma_m: float) -> float:
        """The encoder's."""
        return encoder_sigma_m

    def angle_sigma_rad(self) -> float | None:
        """None: no angle is read."""
        return None

    def noise_mm(self, sigma_m: float, resolution_m: float) -> dict[str, float]:
        """The encoder's σ and resolution."""
        return {"sigma_mm": float(m_to_mm(sigma_m)),
                "resolution_mm": float(m_to_mm(resolution_m))}

    def rigs(self, rng: np.random.Generator) -> tuple[Rig, Rig]:
        """The true ports, and each told with an N(0, σ²) error per axis (or as given)."""
        told = np.array([port + rng.normal(0.0, 1.0, 3) * self.port_error_m
                         for port in self.stations_m]).reshape(-1, 3)
        if self.port_told_m is not None:
            told = self.port_told_m[None]
        return (Rig(self.stations_m, self.station_names, self.attachment_m),
                Rig(told, self.station_names, self.attachment_told_m))

    def capture(self, bench: Bench, rig: Rig, rng: np.random.Generator) -> Captured:
        """The cable's length at rest at poses drawn station after station, read with the
        encoder's noise; the rows name their port when there are several."""
        visit = bench.visit(list(rig.ports_m), rng)
        read_m, outliers = bench.read_lengths(visit.rest.length_m, rng)
        several = len(rig.ports_m) > 1
        data = length_measurements(visit.q_rad, read_m, port=visit.station if several else None,
                                   port_names=rig.port_names if several else (),
                                   approach=visit.approach)
        return Captured(data, visit.rest, outliers, visit.joint_sigma_rad)

    def truth(self, rig: Rig) -> dict[str, Any]:
        """Nothing beyond the ports."""
        return {}


def read_cable(tables: Mapping[str, Fields]) -> CableSetup:
    """``[cable]`` (the eyelet), ``[port]`` (one port or ``[port.stations_mm]``); no
    ``[measurement]`` keys but the kind, no ``[fixture]``.

    Raises:
        InputError: naming the key that is wrong or does not apply.
    """
    measurement, cable, port = tables["measurement"], tables["cable"], tables["port"]
    for key in ("sigma_mm", "tracker_pose", "attachment_mm", "told_attachment_mm"):
        if measurement.has(key):
            raise measurement.error(key, f"{key} with cable lengths",
                                    "[encoder] for the cable's noise, [cable] for its "
                                    "attachment")
    attachment = mm_to_m(cable.vector("attachment_mm", 3, default=[0.0, 0.0, 0.0]))
    told = mm_to_m(cable.vector("told_attachment_mm", 3)) \
        if cable.has("told_attachment_mm") else attachment
    names: tuple[str, ...] = ()
    stations = np.zeros((0, 3))
    moved = port.has("stations_mm")
    if moved:
        if port.has("position_mm"):
            raise port.error("stations_mm", "stations with position_mm or without cable "
                             "lengths", "either position_mm or [port.stations_mm]")
        block = port.table("stations_mm")
        names = tuple(str(name) for name in block.values)
        if not names:
            raise port.error("stations_mm", "no station", "one or more name = [x, y, z]")
        stations = np.stack([mm_to_m(block.vector(name, 3)) for name in names])
    if not moved:
        port.required("position_mm", "the true port [x, y, z] in mm (or [port.stations_mm])")
        names, stations = ("port",), mm_to_m(port.vector("position_mm", 3))[None]
    if port.has("told_mm") and port.has("told_error_mm"):
        raise port.error("told_mm", "both told_mm and told_error_mm", "at most one of them")
    if port.has("told_mm") and moved:
        raise port.error("told_mm", "told_mm with stations", "told_error_mm for every station")
    told_m = mm_to_m(port.vector("told_mm", 3)) if port.has("told_mm") else None
    return CableSetup(attachment, told, names, stations, told_m,
                      float(mm_to_m(port.number("told_error_mm", 0.0, minimum=0.0))))
