"""The one interface of a measurement kind: everything about one kind of reading, in one place.

A kind (a cable length, a tracker position, a fixed point…) owns its whole path:

- **readings**: the columns it keeps in :class:`~twin.dataset.Measurements` (values and labels
  under its own names), the file columns they are read from and written to (:attr:`Kind.columns`,
  :meth:`Kind.from_columns`, :meth:`Kind.to_columns`) and their validation;
- **the model**: residuals and their derivatives from where the measured point is
  (:class:`Measured`, which the model computes from the robot), the measurement-stage unknowns it
  reads (:attr:`Kind.groups`), the readings the model predicts (:meth:`Kind.measure`), the gauge
  its cost is flat along (:meth:`Kind.symmetries`);
- **the calibration**: what it needs of the rig and starts from the data (:meth:`Kind.prepare`,
  :meth:`Kind.start`), how its readings' size is judged (:meth:`Kind.units_ratio`), what
  ``twin predict`` gives (:meth:`Kind.predict`);
- **what a user sees**: its report lines (:meth:`Kind.describe`, :meth:`Kind.summary`) and its
  drawing in Rerun (:meth:`Kind.draw`, on a :class:`Canvas` the viewer adapter implements);
- **the twin**: what a scenario says of its instrument and how that instrument measures on
  the twin (:meth:`Kind.read_setup`, :mod:`twin.kinds.bench`).

Nothing outside :mod:`twin.kinds` asks which kind a measurement is: a new kind is one module
and its line in :data:`twin.kinds.KINDS`.

Residual rows: ``rows_per_pose`` per pose, pose by pose, then any rows that belong to no pose (a
known distance between two fixed points, say).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, ClassVar, NamedTuple, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import Array
from twin.dataset import Labels, Measurements
from twin.kinds.bench import Fields, Setup
from twin.rig import Part, Rig
from twin.robot import RobotModel

if TYPE_CHECKING:
    from twin.model import Model

ANCHOR_RADIUS_M = 0.012
"""Radius a fixed part of the rig (a port) is drawn with, m."""
MARK_RADIUS_M = ANCHOR_RADIUS_M / 2
"""Radius a measured point or a fixed place is drawn with, m."""


class Measured(NamedTuple):
    """Where the measured point is at every pose, as the model computes it."""

    position_m: Array
    """The measured point in the base frame, shape (..., m, 3), m."""
    rotation: Array | None = None
    """The flange's orientation in the base frame, base_R_flange, shape (..., m, 3, 3); None
    unless the kind reads orientations (:attr:`Kind.reads_rotation`)."""


class Ranges(NamedTuple):
    """A kind's rows as distances from anchors (:meth:`Kind.ranges`)."""

    anchors_m: Array
    """The anchor of each row, shape (m, 3) or (..., m, 3) with the values (..., p_g), m."""
    residuals: Callable[[Array], Array]
    """The residuals (..., M) from the measured point's distances (..., m) from the anchors,
    m: the kind's :meth:`Kind.residuals` alike."""
    readings_m: Array | None = None
    """Each row's reading, shape (m,), m, when every residual is the distance less it, one
    row per pose and nothing else (no scale or offset estimated): then a least-squares cost
    is summed in the distances' pass (:meth:`twin.model.Model.sum_squares`). None otherwise."""


class Noise(NamedTuple):
    """The noise of one reading a calibration is told: what weighs a kind's rows of different
    units against each other (an orientation's against a position's)."""

    sigma_m: float
    """Of a length or coordinate, m."""
    sigma_rad: float | None = None
    """Of an angle, rad; None: the kind's own default."""


class UnitHint(NamedTuple):
    """A hint that an input looks given in another unit than millimetres."""

    readings: bool
    """True when the measurement file looks wrong, False when the rig (a flag) does."""
    text: str
    """What looks wrong and what it probably is, one sentence."""


class KindJacobian(NamedTuple):
    """Residuals at one x and their derivatives."""

    residuals: Array
    """r, shape (M,), in the measurement's unit (m)."""
    by_position: Array
    """∂r/∂p of each pose's rows w.r.t. that pose's point, shape (m, rows_per_pose, 3)."""
    by_group: dict[str, Array]
    """∂r/∂x_g of each measurement-stage group the kind reads, shape (M, p_g)."""
    by_rotation: Array | None = None
    """∂r/∂ω of each pose's rows w.r.t. a small turn ω of the flange about the base axes
    (base_R_flange → Exp(ω) base_R_flange), shape (m, rows_per_pose, 3); None for kinds that
    do not read orientations."""


class Canvas(Protocol):
    """Where a kind draws what was measured, in the base frame, one entry per pose on the pose
    timeline (the Rerun scene implements it: :mod:`twin.viz.scene`). ``leaf`` names the entity
    under ``world/``."""

    def anchors(self, leaf: str, points_m: Array, labels: Sequence[str], radius_m: float
                ) -> None:
        """Fixed parts of the rig, drawn once: points (k, 3), m, with a label each."""
        ...

    def marks(self, leaf: str, points_m: Array, labels: Sequence[str], radius_m: float) -> None:
        """A point per pose: points (m, 3), m, with a label each."""
        ...

    def lines(self, leaf: str, starts_m: Array, ends_m: Array, labels: Sequence[str]) -> None:
        """A segment per pose: from starts (m, 3) to ends (m, 3), m, with a label each."""
        ...


def no_symmetries(model: Model, x: Array) -> Array:
    """No direction to project out: shape (p, 0)."""
    return np.zeros((model.n_params, 0))


ORIGIN_TOL_M = 1e-12
"""A chain's fixed base or tool translation, or a known attachment, shorter than this counts as
none (a common scale of every length is then a symmetry: nothing of fixed length is left)."""


def length_scale(model: Model, x: Array) -> Array | None:
    """A common scale of every length the model holds, as a direction of x (p,): the table's
    lengths and the estimated attachment, about the base origin; the kind adds its own places.
    None when something of fixed length is left (a base or tool translation, a known
    attachment off the flange), which pins the scale."""
    structure = model.robot.structure
    fixed = max(np.linalg.norm(structure.base[:3, 3]), np.linalg.norm(structure.tool[:3, 3]))
    attachment_fixed = not model.has("attachment") \
        and np.linalg.norm(model.rig.attachment_m) > ORIGIN_TOL_M
    if fixed >= ORIGIN_TOL_M or attachment_fixed:
        return None
    scale = np.zeros(model.n_params)
    scale[model.slice("dh")] = np.where(structure.is_length, model.table(x), 0.0).ravel()
    if model.has("attachment"):
        scale[model.slice("attachment")] = model.point(x)
    return scale


def mm_cells(values_mm: Array) -> list[str]:
    """Cells of a file column, mm (or any unit), exactly round-tripping floats."""
    return [repr(float(v)) for v in values_mm]


class Kind(ABC):
    """A measurement kind (module docstring). Subclasses set the class attributes and
    implement the abstract methods; the others have the defaults of a kind that needs nothing
    more."""

    name: ClassVar[str]
    """The kind's name in :data:`twin.kinds.KINDS` and in files (``length``, ``position``…)."""
    what: ClassVar[str]
    """What its readings are, for messages (``cable lengths``)."""
    rows_per_pose: ClassVar[int]
    """Residual rows per pose: 1 for a length, 3 for a position."""
    groups: ClassVar[tuple[str, ...]] = ()
    """The measurement-stage unknown groups it reads."""
    implied: ClassVar[tuple[str, ...]] = ()
    """Groups identified whenever data of this kind are fitted (the fixed points of fixed-point
    data: nothing else tells where they are)."""
    columns: ClassVar[tuple[str, ...]] = ()
    """Its numeric columns in a measurement file, each required."""
    unitless: ClassVar[tuple[str, ...]] = ()
    """Those of its columns that are not lengths (a quaternion's): an importer told another
    length unit leaves them as written."""
    labels: ClassVar[tuple[str, ...]] = ()
    """Its label (text) columns in a measurement file that are required."""
    optional_labels: ClassVar[tuple[str, ...]] = ()
    """Its label columns that may be absent (the ``port`` of cable lengths)."""
    columns_text: ClassVar[str]
    """Its columns with their units, for messages (``length (mm)``)."""
    messages: ClassVar[tuple[str, ...]] = ()
    """ROS message types whose data are its readings, in its columns' order and SI (what the
    bag importer reads: ``std_msgs/msg/Float64`` a length)."""
    flags: ClassVar[tuple[tuple[str, str], ...]] = ()
    """Rig flags that apply to this kind alone, each with what it says about the kind
    (``("--port", "cable lengths (a port per reading)")``)."""
    reading_noun: ClassVar[str] = "readings"
    """What one calls its readings in a sentence (``lengths``)."""
    on_flange: ClassVar[bool] = False
    """Whether the instrument reads the flange centre unless told otherwise (a cable hooks on
    the flange), so that its measured point is worth naming only when it is off the flange (a
    tracker target or a ball is always named)."""
    measurement_keys: ClassVar[tuple[str, ...]] = ()
    """The keys of a scenario's ``[measurement]`` table it reads, beside ``kind``."""
    encoder_keys: ClassVar[tuple[str, ...]] = ()
    """The keys of a scenario's ``[encoder]`` table that only its readings take (a cable
    encoder's zero and scale); a scenario of another kind may not have them."""
    scenario_tables: ClassVar[tuple[tuple[str, tuple[str, ...]], ...]] = ()
    """The scenario tables it alone reads, each with its keys (``[fixture]`` of fixed points);
    a scenario of another kind may not have them."""
    in_instrument_frame: ClassVar[bool] = False
    """Whether its readings are in the instrument's own frame (the rig's
    :attr:`~twin.rig.Rig.base_in_tracker`), which results keep and the twin's truth states."""
    reads_rotation: ClassVar[bool] = False
    """Whether its residuals read the tool frame's orientation (:attr:`Measured.rotation`)."""
    prediction_note: ClassVar[str] = ""
    """What its :meth:`prediction_columns` are, beside their names (`` (mm, tracker frame)``)."""
    point_rows: ClassVar[tuple[int, ...]] = ()
    """For a kind that reads more than a point, which of each pose's rows are the point's (a
    pose's x, y, z): the identifiability report names what the other rows add."""
    beyond_noun: ClassVar[str] = ""
    """What the rows beyond the point's are (``orientations``)."""
    random_poses: ClassVar[bool] = True
    """Whether its readings at random well-spread poses can stand for its data (what the
    identifiability of well-spread poses compares with); not for fixed points, which random
    poses never bring to a common place."""

    # --- the model ------------------------------------------------------------------------

    @abstractmethod
    def template(self, q_rad: Array, rig: Rig, labels: Mapping[str, NDArray[np.intp]]
                 ) -> Measurements:
        """Poses where nothing was read, as measurements of this kind with zero readings: for
        positions, flanges and Jacobians at poses of one's choosing.

        Args:
            q_rad: Joint angles, shape (m, n), rad.
            rig: The rig the model has (the names of its ports or places).
            labels: The index of each row into the kind's labels (``port``, ``point``), shape
                (m,) each; the first (index 0) for labels not given.
        """

    @abstractmethod
    def residuals(self, at: Measured, values: Mapping[str, Array], data: Measurements,
                  rig: Rig) -> Array:
        """Residuals for the measured point (..., m, 3) and group values (..., p_g): shape
        (..., M)."""

    @abstractmethod
    def jacobian(self, at: Measured, values: Mapping[str, Array], data: Measurements,
                 rig: Rig) -> KindJacobian:
        """Residuals and derivatives at one x: the measured point (m, 3), values (p_g,)."""

    @abstractmethod
    def measure(self, at: Measured, values: Mapping[str, Array], template: Measurements,
                rig: Rig) -> Measurements:
        """Noise-free readings of this kind at the measured point (m, 3) and values (p_g,),
        on the template's rows (:meth:`template`): the data the model fits exactly (for
        identifiability on synthetic poses, and for tests)."""

    def ranges(self, values: Mapping[str, Array], data: Measurements, rig: Rig
               ) -> Ranges | None:
        """Where each row reads the distance of the measured point from an anchor and its
        residual follows from that distance alone: the anchors and how (:class:`Ranges`) — the
        model then computes the distances in one pass of the chain, never the points. None (the
        default): the residuals need the points (:meth:`residuals`)."""
        return None

    def symmetries(self, model: Model, x: Array) -> Array:
        """Directions of x (p, g) along which the kind's cost is exactly flat although its
        linearised rows are not (they move the residuals only by rotating or scaling them):
        the known gauge group that :meth:`twin.model.Model.identifiable_jacobian` projects out.
        Empty (p, 0) for kinds whose gauge freedoms are exact null directions of the Jacobian.
        """
        return no_symmetries(model, x)

    def pivot(self, rig: Rig) -> Array | None:
        """A fixed point of the instrument whose turns the data may not see (the port one
        cable runs from: a turn about the vertical through it), shape (3,), base frame, m; None
        when the instrument has none. The gauge (:mod:`twin.analysis.gauge`) names motions
        about it."""
        return None

    # --- the calibration ------------------------------------------------------------------

    def prepare(self, robot: RobotModel, rig: Rig, data: Measurements, noise: Noise
                ) -> tuple[Rig, Measurements]:
        """The rig and data a calibration fits: the rig completed from the data (the places
        they name) and the noise (how its rows weigh), the data's labels matched to the rig's
        (its ports by name).

        Raises:
            InputError: for what the rig lacks or the data name that the rig does not have.
        """
        return rig, data

    def implied_by(self, rig: Rig) -> tuple[str, ...]:
        """The groups identified whenever data of this kind are fitted with this rig (the
        prepared one): :attr:`implied`, and what the rig's data bring (a zero per capture
        session of cable lengths)."""
        return self.implied

    def start(self, model: Model, train: Measurements) -> Model:
        """The model with its rig started from the training data where the settings leave it
        unknown (a tracker frame at a rigid fit)."""
        return model

    def align(self, model: Model, data: Measurements) -> Model:
        """The nominal model as its readings can be compared with the data: the instrument's
        own frame fitted to them, for kinds that read in one."""
        return model

    def units_ratio(self, data: Measurements, nominal: Array) -> float | None:
        """The readings' size over the nominal model's (residual rows ``nominal`` (M,), m), or
        None when the kind has no size to compare: far from 1, the data are likely in other
        units."""
        return None

    def unit_hint(self, rig: Rig, data: Measurements) -> UnitHint | None:
        """A hint when the rig or the readings look given in other units than millimetres
        (None: none)."""
        return None

    def predict(self, model: Model, x: Array, poses: Measurements) -> dict[str, Array]:
        """The readings the identified model predicts at poses (:meth:`template` rows), by
        name: what ``twin predict`` writes beside the measured point (none by default)."""
        return {}

    def read_part(self, document: Any) -> Part | None:
        """The kind's part of the rig from a result file (:meth:`twin.rig.Part.document`; None
        when the file has none).

        Raises:
            InputError: naming the key that is wrong (no source: the reader adds the file).
        """
        return None

    def report(self, model: Model, x: Array) -> list[str]:
        """Lines of the text report about what only this kind knows: its part of the rig as
        identified (a tool's rotation); none by default."""
        return []

    # --- files ----------------------------------------------------------------------------

    @abstractmethod
    def from_columns(self, q_rad: Array, numbers: Mapping[str, Array],
                     labels: Mapping[str, list[str]], lines: Sequence[int],
                     approach: NDArray[np.int8] | None) -> Measurements:
        """Measurements from a file's columns: ``numbers`` each shape (m,) as written (mm…),
        ``labels`` one text per row, ``lines`` each row's line number.

        Raises:
            InputError: naming the line and column of a reading out of range (no source: the
                reader adds the file).
        """

    @abstractmethod
    def to_columns(self, data: Measurements) -> list[tuple[str, list[str]]]:
        """The file columns of the readings: (header, one cell per row) each."""

    def prediction_columns(self, predicted: Mapping[str, Array]) -> list[tuple[str, Array]]:
        """The columns ``twin predict`` writes for :meth:`predict`'s readings: (header,
        values (m,) in file units) each."""
        return []

    # --- what a user sees -----------------------------------------------------------------

    @abstractmethod
    def describe(self, rig: Rig, data: Measurements) -> str:
        """The rig in a few words for a report (``port (600.000, -400.000, 100.000) mm``)."""

    def summary(self, data: Measurements) -> str:
        """The readings' range for a report (``, cable lengths 512.3 … 1203.4 mm``), or ""."""
        return ""

    @abstractmethod
    def draw(self, canvas: Canvas, rig: Rig, data: Measurements, points_m: Array) -> None:
        """What was measured at every pose, with the measured point drawn at ``points_m``
        (m, 3), m (the cable from its port, the point and its reading…)."""

    # --- the twin (:mod:`twin.kinds.bench`) ----------------------------------------------

    @abstractmethod
    def read_setup(self, tables: Mapping[str, Fields]) -> Setup:
        """The kind's instrument as a scenario describes it: its tables (``[measurement]``,
        ``[cable]``, ``[port]``, ``[fixture]``…, by name) read into its own value, which
        measures on the twin.

        Raises:
            InputError: naming the key that is wrong or does not apply to this kind.
        """

    def deviation(self, rest: Any, rigid_m: Array, rig: Rig, data: Measurements) -> Array:
        """How far the twin's noise-free readings (``rest``, :class:`~twin.kinds.bench.Rest`)
        lie from the true robot's rigid model (its measured points (m, 3), m), per row, m:
        what no D-H fit can absorb. The measured point's 3-D gap by default."""
        return np.asarray(rest.point_m - rigid_m, dtype=np.float64).ravel()


class PlaceKind(Kind):
    """A kind whose readings are one label: the unknown place each row's measured point was
    brought to (a fixed point, a plane), named in a file column of the label's name."""

    place: ClassVar[str]
    """The label's name, and its file column."""

    def labelled(self, q_rad: ArrayLike, index: ArrayLike, names: Sequence[str] = (),
                 approach: ArrayLike | None = None) -> Measurements:
        """Measurements of this kind: joint angles (m, n), rad, each row's place (m,), the
        places' names if known, the approach directions (m, n) if recorded."""
        return Measurements(np.asarray(q_rad, dtype=np.float64), self.name,
                            labels={self.place: Labels(tuple(names),
                                                       np.asarray(index, dtype=np.intp))},
                            approach=None if approach is None else np.asarray(approach))

    def from_columns(self, q_rad: Array, numbers: Mapping[str, Array],
                     labels: Mapping[str, list[str]], lines: Sequence[int],
                     approach: NDArray[np.int8] | None) -> Measurements:
        """The places' names."""
        places = Labels.of(labels[self.place])
        return self.labelled(q_rad, places.indices, places.names, approach)

    def to_columns(self, data: Measurements) -> list[tuple[str, list[str]]]:
        """The places' names (``point1``… for unnamed ones)."""
        return [(self.place, data.labels[self.place].per_row(self.place))]
