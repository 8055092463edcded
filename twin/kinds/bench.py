"""A measurement kind's instrument in the twin: what a scenario says of it, and how it measures.

Each kind reads its part of a scenario file into its own frozen value, a :class:`Setup`
(:meth:`twin.kinds.base.Kind.read_setup`, from :class:`Fields`: the scenario reader's tables),
and that value measures on the twin: it gives the true and the told rig, and makes the readings
from what the twin offers it (:class:`Bench`: poses at rest, poses that touch given places, the
encoder's noise). The MuJoCo twin (:mod:`twin.sim.simulate`) implements the bench; nothing here
imports it, and nothing there asks which kind it serves.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple, Protocol

import numpy as np
from numpy.typing import NDArray

from twin.arrays import Array, frozen_array
from twin.dataset import Measurements
from twin.errors import InputError
from twin.geometry.rigid import transform
from twin.rig import Rig
from twin.robot import RobotModel
from twin.units import deg_to_rad, m_to_mm, mm_to_m


class Fields(Protocol):
    """A table of a scenario file, as a kind reads its own keys (the scenario reader's
    :class:`twin.io.table.Table`: every mistake an :class:`~twin.errors.InputError` naming the
    file and the key)."""

    values: Mapping[str, Any]

    def has(self, key: str) -> bool:
        """Whether the table holds ``key``."""
        ...

    def error(self, key: str | None, found: str, expected: str) -> InputError:
        """The error of ``key`` (or of the whole table)."""
        ...

    def required(self, key: str, expected: str) -> Any:
        """The value of ``key``; an error naming ``expected`` when absent."""
        ...

    def table(self, key: str, *, allowed: Iterable[str] | None = None, kind: str = "",
              expected: str = "a table") -> Fields:
        """The table under ``key`` (empty when absent)."""
        ...

    def integer(self, key: str, default: int | None = None, *, minimum: int | None = None,
                maximum: int | None = None, expected: str | None = None) -> int:
        """A whole number within the bounds."""
        ...

    def boolean(self, key: str, default: bool | None = None) -> bool:
        """``true`` or ``false``."""
        ...

    def number(self, key: str, default: float | None = None, *, minimum: float | None = None,
               maximum: float | None = None, strict_minimum: bool = False,
               strict_maximum: bool = False, expected: str | None = None) -> float:
        """A finite number within the bounds."""
        ...

    def vector(self, key: str, length: int, *, per_joint: bool = False,
               minimum: float | None = None, within: float | None = None,
               default: float | list[float] | None = None,
               expected: str | None = None) -> Array:
        """``length`` finite numbers (one for all, when ``per_joint``), shape (length,)."""
        ...

    def rows(self, key: str, width: int, *, expected: str) -> Array:
        """A non-empty list of lists of ``width`` numbers, shape (k, width)."""
        ...


class Rest(Protocol):
    """The arm at rest at recorded joint angles, as the twin computes it."""

    q_rad: Array
    """Actual joint angles, shape (m, n), rad."""
    length_m: Array
    """Cable lengths from each row's port, shape (m,), m; NaN without a cable."""
    point_m: Array
    """The measured point in the base frame, shape (m, 3), m."""
    rotation: Array
    """The flange's orientation in the base frame, base_R_flange, shape (m, 3, 3)."""


class Visit(NamedTuple):
    """Poses visited on the twin (:meth:`Bench.visit`)."""

    q_rad: Array
    """The joint angles as recorded (to the controller's resolution), shape (m, n), rad."""
    station: NDArray[np.intp]
    """The station (index into the stations visited) of each pose, shape (m,)."""
    rest: Any
    """Where the arm was at rest (:class:`Rest`)."""
    joint_sigma_rad: float
    """The joint jitter 1σ behind the robot's repeatability, rad."""
    approach: NDArray[np.int8]
    """The direction each joint last moved in before each pose, shape (m, n), ±1."""


class Captured(NamedTuple):
    """What an instrument measured on the twin (:meth:`Setup.capture`)."""

    measurements: Measurements
    """Recorded joint angles and readings, as written."""
    rest: Any
    """Where the arm was at rest (:class:`Rest`): the truth of every reading."""
    outlier_rows: NDArray[np.intp]
    """Rows that carry a gross error."""
    joint_sigma_rad: float
    """The joint jitter 1σ behind the repeatability, rad."""


class Bench(Protocol):
    """The twin as an instrument measures on it (:mod:`twin.sim.simulate`)."""

    robot: RobotModel
    """The true robot."""

    def visit(self, stations_m: Sequence[Array | None], rng: np.random.Generator) -> Visit:
        """Poses from the scenario's plan or drawn feasible for each station in turn (a cable
        from the station's port, or none), the joint jitter, and the arm at rest; each station
        its share of the scenario's poses (the first ones the remainder); the angles as the
        controller records them."""
        ...

    def touch(self, places_m: Array, touches: int, sigma_m: Array, rng: np.random.Generator
              ) -> tuple[Array, NDArray[np.intp]]:
        """Configurations of the true robot that bring the measured point into each place
        (f, 3), m, ``touches`` times, seated with an error of σ (3,) per axis: joint angles
        (f · touches, n), rad, and each row's place."""
        ...

    def rigid(self, q_rad: Array) -> Any:
        """The true robot at rest at q (m, n) without the twin's joint errors (:class:`Rest`,
        no cable)."""
        ...

    def read_lengths(self, length_m: Array, rng: np.random.Generator
                     ) -> tuple[Array, NDArray[np.intp]]:
        """Encoder readings of true lengths (m,), m, with the scenario's encoder noise, and
        the rows with an outlier."""
        ...


class Setup(Protocol):
    """What a scenario says of a kind's instrument (:meth:`twin.kinds.base.Kind.read_setup`):
    the kind's own frozen value, which measures on the twin."""

    @property
    def attachment_m(self) -> Array:
        """The true measured point in the flange frame, shape (3,), m."""
        ...

    @property
    def attachment_told_m(self) -> Array:
        """The attachment the calibration is told, shape (3,), m."""
        ...

    @property
    def ports_m(self) -> Array:
        """The true ports of the cables the twin builds, shape (k, 3), m (none: no cable)."""
        ...

    @property
    def pose_count(self) -> int | None:
        """The poses the instrument sets (touches of every place), or None: the scenario's
        ``[poses]``."""
        ...

    def instrument_sigma_m(self, encoder_sigma_m: float) -> float:
        """The noise 1σ of one reading the instrument states, m, given the scenario's encoder
        noise (σ with its resolution folded in)."""
        ...

    def angle_sigma_rad(self) -> float | None:
        """The noise 1σ of one angle reading the instrument states, rad; None: it reads no
        angle."""
        ...

    def noise_mm(self, sigma_m: float, resolution_m: float) -> dict[str, float]:
        """The instrument's noise as a capture file's ``[encoder]`` table states it, mm, given
        the scenario's encoder noise σ and resolution, m."""
        ...

    def rigs(self, rng: np.random.Generator) -> tuple[Rig, Rig]:
        """The true rig and the rig the calibration is told (drawing the told errors)."""
        ...

    def capture(self, bench: Bench, rig: Rig, rng: np.random.Generator) -> Captured:
        """Measure on the twin, the true rig ``rig``."""
        ...

    def truth(self, rig: Rig) -> dict[str, Any]:
        """What truth.json says of the instrument beyond the rig's ports and fixed points (a
        tracker's pose), mm and degrees."""
        ...


def per_axis_sigma(sigma_m: Array) -> float:
    """The RMS of a noise 1σ given per axis (3,), m: one reading's σ."""
    return float(np.sqrt(np.mean(sigma_m**2)))


@dataclass(frozen=True)
class TargetSetup:
    """What every instrument that reads a target on the tool has (a tracker's target, a ball,
    a probe, a 6-D frame's origin), with the defaults of one that reads it with a noise per
    axis, sets no poses of its own and builds no cable; each kind's setup adds its own.

    Attributes:
        attachment_m: The true target in the flange frame, shape (3,), m.
        attachment_told_m: The target the calibration is told, shape (3,), m.
        sigma_m: Noise 1σ per axis of a reading (a ball's seating, a probe's trigger), shape
            (3,), m.
    """

    attachment_m: Array
    attachment_told_m: Array
    sigma_m: Array

    def __post_init__(self) -> None:
        for name in ("attachment_m", "attachment_told_m", "sigma_m"):
            object.__setattr__(self, name, frozen_array(getattr(self, name), (3,), name))

    @property
    def ports_m(self) -> Array:
        """No cable: shape (0, 3)."""
        return np.zeros((0, 3))

    @property
    def pose_count(self) -> int | None:
        """None: the scenario's ``[poses]`` set them."""
        return None

    def instrument_sigma_m(self, encoder_sigma_m: float) -> float:
        """The RMS of the per-axis σ."""
        return per_axis_sigma(self.sigma_m)

    def angle_sigma_rad(self) -> float | None:
        """None: no angle is read."""
        return None

    def noise_mm(self, sigma_m: float, resolution_m: float) -> dict[str, float]:
        """The RMS of the per-axis σ."""
        return {"sigma_mm": float(m_to_mm(per_axis_sigma(self.sigma_m)))}

    def truth(self, rig: Rig) -> dict[str, Any]:
        """Nothing beyond the rig's fixed points."""
        return {}


POSE_TEXT = "[x, y, z, rx, ry, rz] in mm and degrees"
"""How a pose is written in a scenario: position (mm) and fixed-axis angles (deg, R = Rz Ry Rx)."""


def pose_mm_deg(values: Array) -> Array:
    """``[x, y, z, rx, ry, rz]`` (mm, deg; R = Rz Ry Rx) as a 4×4 transform, m."""
    return transform(mm_to_m(values[:3]), deg_to_rad(values[3:]))


def refuse(fields: Fields, found: str, expected: str) -> None:
    """Refuse a table that should be empty, naming its first key."""
    if fields.values:
        raise fields.error(sorted(fields.values)[0], found, expected)


TARGET_KEYS = ("sigma_mm", "tracker_pose", "attachment_mm", "told_attachment_mm")
"""The ``[measurement]`` keys of an instrument that reads a target in its own frame."""


class Target(NamedTuple):
    """What a scenario's ``[measurement]`` says of an instrument that reads a target on the
    tool (a tracker, a ball, a probe), read by :func:`read_target`."""

    attachment_m: Array
    """The true target in the flange frame, shape (3,), m."""
    attachment_told_m: Array
    """The target the calibration is told, shape (3,), m."""
    sigma_m: Array
    """Noise 1σ per axis of a reading (or of a ball's seating), shape (3,), m."""
    frame: Array
    """The instrument's true frame: where the base sits in it (``tracker_pose``), (4, 4), m;
    the identity when not given."""


def read_target(tables: Mapping[str, Fields], name: str, *, frame: bool) -> Target:
    """The ``[measurement]`` table of a kind ``name`` that reads a target: no ``[cable]``, no
    stations, the target (``attachment_mm``, ``told_attachment_mm``), ``sigma_mm`` and, for a
    kind that reads in the instrument's frame (``frame``), ``tracker_pose``.

    Raises:
        InputError: naming the key that does not apply.
    """
    measurement, cable, port = tables["measurement"], tables["cable"], tables["port"]
    refuse(cable, f"a [cable] table with {name} measurements", "[measurement] attachment_mm")
    attachment = mm_to_m(measurement.vector("attachment_mm", 3, default=[0.0, 0.0, 0.0]))
    told = mm_to_m(measurement.vector("told_attachment_mm", 3)) \
        if measurement.has("told_attachment_mm") else attachment
    if port.has("stations_mm"):
        raise port.error("stations_mm", "stations with position_mm or without cable "
                         "lengths", "either position_mm or [port.stations_mm]")
    sigma = measurement.vector("sigma_mm", 3, per_joint=True, minimum=0.0, default=0.0)
    tracker = pose_mm_deg(measurement.vector("tracker_pose", 6, expected=POSE_TEXT)) \
        if measurement.has("tracker_pose") else np.eye(4)
    if not frame and measurement.has("tracker_pose"):
        raise measurement.error("tracker_pose", f"a tracker with {name} measurements",
                                "kind = \"position\"")
    return Target(attachment, told, mm_to_m(sigma), tracker)


def refuse_port(tables: Mapping[str, Fields], name: str) -> None:
    """Refuse a ``[port]`` table (only cable lengths have ports)."""
    refuse(tables["port"], f"a port with {name} measurements",
           "no [port] table (only cable lengths have ports)")
