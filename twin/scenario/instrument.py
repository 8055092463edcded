"""The instrument a scenario measures with (pure values): a measurement kind and what the
scenario says of it, read and owned by the kind (:meth:`twin.kinds.base.Kind.read_setup`, a
:class:`twin.kinds.bench.Setup`):

- **a cable** (``length``): one drawstring encoder from one port, or moved between stations;
  each station's poses are drawn for that station (its cable range and line of sight), its rows
  name it;
- **a laser tracker** (``position``): the measured point at rest, carried into the tracker's
  frame by the true ``base_in_tracker`` and read with Gaussian noise of σ per axis;
- **fixed points** (``point``): a fixture with sockets (a ball bar) set down at several
  placements; for each socket the arm brings the ball (the measured point) into it from
  ``touches`` different configurations, found on the twin (:mod:`twin.sim.touches`). The ball
  seats with an error of σ per axis.
"""

from __future__ import annotations

from dataclasses import dataclass

from twin.arrays import Array
from twin.kinds import KINDS, Kind
from twin.kinds.bench import Setup


@dataclass(frozen=True)
class Instrument:
    """How the twin measures.

    Attributes:
        kind: The measurement kind's name (:data:`twin.kinds.KINDS`).
        setup: What the scenario says of the instrument, the kind's own value.
    """

    kind: str
    setup: Setup

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"kind {self.kind!r}: expected one of {', '.join(KINDS)}")

    @property
    def measures(self) -> Kind:
        """The measurement kind."""
        return KINDS.lookup(self.kind)

    @property
    def attachment_m(self) -> Array:
        """The true measured point in the flange frame, shape (3,), m."""
        return self.setup.attachment_m

    @property
    def attachment_told_m(self) -> Array:
        """The attachment the calibration is told, shape (3,), m."""
        return self.setup.attachment_told_m
