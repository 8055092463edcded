"""The instrument a scenario measures with, beyond one cable from one port (pure values).

- **Stations**: one drawstring encoder moved between several ports; each station's poses are
  drawn for that station (its cable range and line of sight), its rows name it.
- **Laser tracker**: the measured point at rest, carried into the tracker's frame by the true
  ``base_in_tracker`` and read with Gaussian noise of σ per axis (:func:`tracker_readings`).
- **Fixed points**: a fixture with sockets (a ball bar) set down at several placements; for each
  socket the arm brings the ball (the measured point) into it from ``touches`` different
  configurations, found on the twin (:mod:`twin.sim.touches`). The ball seats with an error of
  σ per axis.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from twin.arrays import Array, frozen_array
from twin.kinds import KINDS
from twin.rig import Distance


def _identity() -> Array:
    return np.eye(4)


@dataclass(frozen=True)
class Instrument:
    """How the twin measures, beyond the paper's single cable (SI).

    Attributes:
        kind: ``length``, ``position`` or ``point`` (:data:`twin.kinds.KINDS`).
        attachment_m: The true measured point in the flange frame, shape (3,), m.
        attachment_told_m: The attachment the calibration is told, shape (3,), m.
        station_names: Names of the encoder's stations (ports); empty: the scenario's one port.
        stations_m: The stations' true ports, base frame, shape (k, 3), m.
        sigma_m: Noise 1σ per axis of a tracker reading or of a ball's seating, shape (3,), m.
        base_in_tracker: The true tracker frame: where the base sits in it, shape (4, 4), m.
        sockets_m: The fixture's sockets in its own frame, shape (s, 3), m.
        placements: Where the fixture is set down, base frame, shape (P, 4, 4), m.
        touches: Configurations per socket and placement.
        tell_distances: Whether the calibration is told the socket spacings.
    """

    kind: str = "length"
    attachment_m: Array = field(default_factory=lambda: np.zeros(3))
    attachment_told_m: Array = field(default_factory=lambda: np.zeros(3))
    station_names: tuple[str, ...] = ()
    stations_m: Array = field(default_factory=lambda: np.zeros((0, 3)))
    sigma_m: Array = field(default_factory=lambda: np.zeros(3))
    base_in_tracker: Array = field(default_factory=_identity)
    sockets_m: Array = field(default_factory=lambda: np.zeros((0, 3)))
    placements: Array = field(default_factory=lambda: np.zeros((0, 4, 4)))
    touches: int = 0
    tell_distances: bool = True

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"kind {self.kind!r}: expected one of {', '.join(KINDS)}")
        for name, shape in (("attachment_m", (3,)), ("attachment_told_m", (3,)),
                            ("sigma_m", (3,)), ("base_in_tracker", (4, 4))):
            object.__setattr__(self, name, frozen_array(getattr(self, name), shape, name))
        stations = np.asarray(self.stations_m, dtype=np.float64).reshape(-1, 3)
        object.__setattr__(self, "stations_m", frozen_array(stations, stations.shape,
                                                            "stations_m"))
        if len(self.station_names) != len(stations):
            raise ValueError("station_names: one name per station expected")
        sockets = np.asarray(self.sockets_m, dtype=np.float64).reshape(-1, 3)
        object.__setattr__(self, "sockets_m", frozen_array(sockets, sockets.shape, "sockets_m"))
        placements = np.asarray(self.placements, dtype=np.float64).reshape(-1, 4, 4)
        object.__setattr__(self, "placements",
                           frozen_array(placements, placements.shape, "placements"))
        if self.kind == "point" and (not len(sockets) or not len(placements)
                                     or self.touches < 1):
            raise ValueError("fixed points need sockets, placements and touches >= 1")

    @property
    def point_names(self) -> tuple[str, ...]:
        """``f<placement>s<socket>`` for every socket of every placement, 1-based."""
        return tuple(f"f{p + 1}s{s + 1}" for p in range(len(self.placements))
                     for s in range(len(self.sockets_m)))

    @property
    def points_m(self) -> Array:
        """Every socket of every placement in the base frame, shape (P·s, 3), m."""
        return np.concatenate([self.sockets_m @ placement[:3, :3].T + placement[:3, 3]
                               for placement in self.placements]) if len(self.placements) \
            else np.zeros((0, 3))

    @property
    def distances(self) -> tuple[Distance, ...]:
        """The spacing of every pair of sockets within each placement (if told)."""
        if not self.tell_distances:
            return ()
        found = []
        names = self.point_names
        count = len(self.sockets_m)
        for p in range(len(self.placements)):
            for a in range(count):
                for b in range(a + 1, count):
                    length = float(np.linalg.norm(self.sockets_m[a] - self.sockets_m[b]))
                    found.append(Distance(names[p * count + a], names[p * count + b], length))
        return tuple(found)


def tracker_readings(points_m: Array, base_in_tracker: Array, sigma_m: Array,
                     rng: np.random.Generator) -> Array:
    """Tracker readings of base-frame points (m, 3): the tracker frame plus N(0, σ²) per axis,
    shape (m, 3), m."""
    seen = points_m @ base_in_tracker[:3, :3].T + base_in_tracker[:3, 3]
    return np.asarray(seen + rng.normal(0.0, 1.0, seen.shape) * sigma_m, dtype=np.float64)
