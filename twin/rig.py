"""The measurement rig as the calibration is told it: where the instrument is, where it hooks.

The nominal values of everything around the robot that a measurement model needs. Each may be
known (used as it is) or an unknown group whose correction is identified with the robot's
errors (:mod:`twin.unknowns`):

- cable ports (:mod:`twin.kinds.length`): group ``port``, for the ports named in
  ``estimated_ports``; a port nobody measured (``unknown_ports``) is started from the data;
- the encoder's zero (group ``offset``), one per capture session (``sessions``);
- the measured point on the tool (cable eyelet, tracker target, ball): group ``attachment``;
- the laser tracker's frame (:mod:`twin.kinds.position`): group ``base``;
- fixed places the tool point was brought to, and known distances between them
  (:mod:`twin.kinds.point`): group ``points``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, NamedTuple, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import Array, frozen_array
from twin.choices import MAX_TENSION_N
from twin.geometry.rigid import is_rigid_transform

PORT_LABELS = "port"
"""The measurement labels (:attr:`twin.dataset.Measurements.labels`) whose indices say which of
:attr:`Rig.ports_m` each row's cable ran from (port 0 without them)."""

SESSION_LABELS = "session"
"""The measurement labels (and file column) naming each row's capture session
(:attr:`Rig.sessions`)."""


def _origin() -> Array:
    return np.zeros(3)


def _identity() -> Array:
    return np.eye(4)


class Distance(NamedTuple):
    """A known distance between two named fixed points (a ball fixture's socket spacing, a
    gauge bar)."""

    first: str
    second: str
    length_m: float
    """The distance, m."""


class Angle(NamedTuple):
    """A known angle between two named planes (a square's faces, a sine bar's): the angle
    between their normals."""

    first: str
    second: str
    angle_rad: float
    """The angle, rad, in (0, π)."""


class Part(Protocol):
    """What a measurement kind keeps in the rig beyond the parts every kind shares: its own
    frozen value (the tool rotation of 6-D poses, the planes of plane data), defined, started,
    read and written by its kind (:mod:`twin.kinds`)."""

    def places(self, group: str) -> tuple[str, ...]:
        """The named places whose corrections the measurement-stage group ``group`` holds (the
        planes of group ``planes``), or () when this part sizes no such group."""
        ...

    def document(self) -> dict[str, Any]:
        """The part as a result file keeps it: what rebuilds the fitted model exactly (its
        kind's ``read_part`` reads it back)."""
        ...


@dataclass(frozen=True)
class Rig:
    """Ports of the cable, the point of the tool that is measured, the tracker's frame and the
    fixed points.

    Attributes:
        ports_m: Cable ports in the robot base frame, shape (k, 3), m; row j is the port a
            measurement with ``port == j`` ran from.
        port_names: A name per port, length k.
        attachment_m: The measured point (cable eyelet, tracker target, ball) in the flange
            frame, shape (3,), m; the flange centre by default.
        tension_n: The cable's pull on the attachment point, towards each row's port, N (a
            drawstring encoder's spring force; its data sheet gives it). It loads the joints
            of a compliant arm (unknown group ``compliance``); 0 for instruments that do not
            touch the robot.
        estimated_ports: The ports whose position the ``port`` group corrects; every port when
            empty.
        unknown_ports: The ports nobody measured: their rows of ``ports_m`` are placeholders
            until the calibration starts them from the data (multilateration,
            :meth:`twin.kinds.length.Length.start`), then starts; the ``port`` group searches
            them without the told port's box.
        sessions: The capture sessions of the data (a ``session`` column), each with its own
            encoder zero (group ``offset``, one per session); empty: one session.
        base_in_tracker: Where the robot base frame sits in the tracker's frame, shape (4, 4), m:
            ``p_tracker = base_in_tracker · p_base``; the identity by default.
        point_names: A name per fixed point, length f.
        points_m: The fixed points in the robot base frame, shape (f, 3), m.
        distances: Known distances between named fixed points (or parallel planes).
        angles: Known angles between named planes.
        part: What the measurement kind keeps beyond these (:class:`Part`), or None.
        temperature_ref_c: The temperature the thermal growth is counted from
            (:mod:`twin.unknowns.thermal`: the mean of the measurements calibrated), °C; None
            without thermal unknowns.
    """

    ports_m: Array = field(default_factory=lambda: np.zeros((0, 3)))
    port_names: tuple[str, ...] = ()
    attachment_m: Array = field(default_factory=_origin)
    tension_n: float = 0.0
    estimated_ports: tuple[str, ...] = ()
    unknown_ports: tuple[str, ...] = ()
    sessions: tuple[str, ...] = ()
    base_in_tracker: Array = field(default_factory=_identity)
    point_names: tuple[str, ...] = ()
    points_m: Array = field(default_factory=lambda: np.zeros((0, 3)))
    distances: tuple[Distance, ...] = ()
    angles: tuple[Angle, ...] = ()
    part: Part | None = None
    temperature_ref_c: float | None = None

    def places(self, group: str) -> tuple[str, ...]:
        """The named places of the kind's part a measurement-stage group corrects
        (:meth:`Part.places`), () without a part."""
        return () if self.part is None else self.part.places(group)

    def __post_init__(self) -> None:
        ports = np.asarray(self.ports_m, dtype=np.float64).reshape(-1, 3)
        object.__setattr__(self, "ports_m", frozen_array(ports, ports.shape, "ports_m"))
        names = tuple(self.port_names) or tuple(
            "port" if len(ports) == 1 else f"port{j + 1}" for j in range(len(ports)))
        if len(names) != len(ports) or len(set(names)) != len(names):
            raise ValueError(f"port_names {names!r}: expected {len(ports)} distinct names")
        object.__setattr__(self, "port_names", names)
        estimated = tuple(self.estimated_ports)
        unknown = [name for name in estimated if name not in names]
        if unknown or len(set(estimated)) != len(estimated):
            raise ValueError(f"estimated_ports {estimated!r}: expected distinct names among "
                             + ", ".join(names))
        object.__setattr__(self, "estimated_ports", estimated)
        unknown_ports = tuple(self.unknown_ports)
        if any(name not in names for name in unknown_ports) \
                or len(set(unknown_ports)) != len(unknown_ports):
            raise ValueError(f"unknown_ports {unknown_ports!r}: expected distinct names among "
                             + ", ".join(names))
        object.__setattr__(self, "unknown_ports", unknown_ports)
        sessions = tuple(str(name) for name in self.sessions)
        if len(set(sessions)) != len(sessions):
            raise ValueError(f"sessions {sessions!r}: expected distinct names")
        object.__setattr__(self, "sessions", sessions)
        object.__setattr__(self, "attachment_m",
                           frozen_array(self.attachment_m, (3,), "attachment_m"))
        if not (np.isfinite(self.tension_n) and 0.0 <= self.tension_n <= MAX_TENSION_N):
            raise ValueError(f"tension_n: {self.tension_n}, expected 0 to {MAX_TENSION_N:g} N")
        object.__setattr__(self, "tension_n", float(self.tension_n))
        tracker = frozen_array(self.base_in_tracker, (4, 4), "base_in_tracker")
        if not is_rigid_transform(tracker):
            raise ValueError("base_in_tracker: not a rigid transform")
        object.__setattr__(self, "base_in_tracker", tracker)
        points = np.asarray(self.points_m, dtype=np.float64).reshape(-1, 3)
        object.__setattr__(self, "points_m", frozen_array(points, points.shape, "points_m"))
        point_names = tuple(self.point_names)
        if len(point_names) != len(points) or len(set(point_names)) != len(point_names):
            raise ValueError(f"point_names {point_names!r}: expected {len(points)} distinct "
                             "names")
        object.__setattr__(self, "point_names", point_names)
        distances = tuple(Distance(str(a), str(b), float(length))
                          for a, b, length in self.distances)
        for distance in distances:
            if distance.first == distance.second or not distance.length_m > 0 \
                    or not np.isfinite(distance.length_m):
                raise ValueError(f"distance {distance}: expected two different points and a "
                                 "positive length")
        object.__setattr__(self, "distances", distances)
        angles = tuple(Angle(str(a), str(b), float(angle)) for a, b, angle in self.angles)
        for angle in angles:
            if angle.first == angle.second or not 0.0 < angle.angle_rad < np.pi:
                raise ValueError(f"angle {angle}: expected two different planes and an angle "
                                 "between 0 and π")
        object.__setattr__(self, "angles", angles)
        if self.temperature_ref_c is not None:
            if not np.isfinite(self.temperature_ref_c):
                raise ValueError("temperature_ref_c: expected a finite temperature, °C")
            object.__setattr__(self, "temperature_ref_c", float(self.temperature_ref_c))

    @classmethod
    def cable(cls, port_m: ArrayLike, attachment_m: ArrayLike | None = None,
              tension_n: float = 0.0) -> Rig:
        """One port, base frame, shape (3,), m; the measured point at ``attachment_m``; the
        cable pulling with ``tension_n`` newtons."""
        return cls(np.asarray(port_m, dtype=np.float64).reshape(1, 3),
                   attachment_m=_origin() if attachment_m is None
                   else np.asarray(attachment_m, dtype=np.float64), tension_n=tension_n)

    @property
    def port_m(self) -> Array:
        """The only port, shape (3,), m.

        Raises:
            ValueError: if the rig has no port or several.
        """
        if len(self.ports_m) != 1:
            raise ValueError(f"the rig has {len(self.ports_m)} ports, not one")
        return self.ports_m[0]

    @property
    def estimated_port_index(self) -> NDArray[np.intp]:
        """Indices of the ports the ``port`` group corrects, shape (e,), in the rig's order."""
        if not self.estimated_ports:
            return np.arange(len(self.ports_m), dtype=np.intp)
        return np.array([j for j, name in enumerate(self.port_names)
                         if name in self.estimated_ports], dtype=np.intp)

    @property
    def distance_index(self) -> NDArray[np.intp]:
        """The two points of each known distance as indices into ``point_names``, shape (d, 2).

        Raises:
            ValueError: naming a distance's point the rig does not have.
        """
        pairs = []
        for distance in self.distances:
            for name in (distance.first, distance.second):
                if name not in self.point_names:
                    raise ValueError(f"distance {distance.first},{distance.second}: no point "
                                     f"{name!r}; the points are "
                                     + (", ".join(self.point_names) or "none"))
            pairs.append((self.point_names.index(distance.first),
                          self.point_names.index(distance.second)))
        return np.array(pairs, dtype=np.intp).reshape(-1, 2)

    @property
    def distances_m(self) -> Array:
        """The known distances, shape (d,), m."""
        return np.array([distance.length_m for distance in self.distances], dtype=np.float64)
