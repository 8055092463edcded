"""6-D poses: a 6-DoF instrument reads where the tool frame is and how it is turned, in its own
frame — a laser tracker's 6-DoF probe (T-Mac style), a camera reading a marker on the tool, a
motion-capture rigid body.

For pose i, six rows. Three of position, as a tracker's (:mod:`twin.kinds.position`)::

    r_p = R_c (R_0 p_i + t_0) + t_c − y_i

with p_i the tool frame's origin in the base frame (the rig's attachment, corrected by group
``attachment``), ``(R_0, t_0)`` the rig's :attr:`~twin.rig.Rig.base_in_tracker` — the
instrument's frame — and ``(R_c, t_c)`` its correction (group ``base``). Three of orientation::

    r_R = w · Log(R_yᵢᵀ R̂_i),   R̂_i = R_c R_0 · base_R_flange,i · R_t Exp(δ)

with R_y the reading, R_t the tool's rotation in the flange frame (:class:`PoseRig`, started at
the data's mean when the tool is estimated), δ its correction (group ``tool``: a rotation
vector applied on the right of R_t), and ``w = σ / σ_θ`` (m/rad) the ratio of the instrument's
position and angle noise (``--sigma``, ``--sigma-deg``): every row then counts as one reading of
noise σ. ``--estimate-tool`` identifies the tool frame whole: its origin (``attachment``) and
its rotation (``tool``).

What orientations see that points do not: a point on the flange axis cannot see a turn of the
flange about it (θ6, and α6 with it), however the arm moves; an orientation turns with it.
:meth:`Pose.report` names the combinations the orientation rows alone make identifiable.

Readings: ``position_m`` (m, 3), m, and ``rotation`` (m, 3, 3), instrument_R_tool. In a file:
``x,y,z`` (mm) and ``qw,qx,qy,qz`` (a unit quaternion, scalar first).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import Array, frozen_array
from twin.choices import DEFAULT_SIGMA_DEG, DEFAULT_SIGMA_MM
from twin.dataset import Measurements
from twin.errors import InputError
from twin.geometry.rigid import (
    angles,
    exp_rotation,
    left_jacobian_inverse,
    log_rotation,
    mean_rotation,
    quaternion_rotation,
    right_jacobian,
    rotation,
    rotation_derivatives,
    rotation_quaternion,
)
from twin.kinds.base import MARK_RADIUS_M, Canvas, Kind, KindJacobian, Measured, Noise, mm_cells
from twin.kinds.bench import (
    TARGET_KEYS,
    Bench,
    Captured,
    Fields,
    TargetSetup,
    per_axis_sigma,
    read_target,
    refuse_port,
)
from twin.kinds.position import (
    COLUMNS,
    POSITION,
    coordinates_hint,
    fit_frame,
    frame_jacobian,
    in_instrument,
    read_xyz_mm,
)
from twin.report.display import xyz_mm
from twin.rig import Part, Rig
from twin.robot import RobotModel
from twin.units import deg_to_rad, m_to_mm, mm_to_m, rad_to_deg

if TYPE_CHECKING:
    from twin.kinds.base import UnitHint
    from twin.model import Model

ROTATION = "rotation"
"""The readings' orientations: instrument_R_tool, shape (m, 3, 3)."""
BASE_ROTATION = "base_rotation"
"""What :meth:`Pose.predict` says of the tool's orientation in the base frame, base_R_tool,
shape (m, 3, 3)."""
QUATERNION = ("qw", "qx", "qy", "qz")
"""The file columns of an orientation: a unit quaternion, scalar first."""
QUATERNION_TOL = 1e-4
"""How far from 1 a quaternion's norm may be (written to 6 decimals, they are some 1e-6 off)."""
DEFAULT_WEIGHT_M_PER_RAD = float(mm_to_m(DEFAULT_SIGMA_MM) / deg_to_rad(DEFAULT_SIGMA_DEG))
"""w when no noise is stated: 0.01 mm against 0.01° (a 6-DoF tracker probe's class), m/rad."""


@dataclass(frozen=True)
class PoseRig:
    """What the pose kind keeps in the rig (:attr:`twin.rig.Rig.part`).

    Attributes:
        tool_rotation: The tool frame's rotation in the flange frame, flange_R_tool, shape
            (3, 3): told (the identity: the flange's), or started at the data's mean when the
            tool is estimated.
        weight_m_per_rad: w = σ / σ_θ, what an orientation row is worth against a position
            row, m/rad.
    """

    tool_rotation: Array
    weight_m_per_rad: float = DEFAULT_WEIGHT_M_PER_RAD

    def __post_init__(self) -> None:
        turn = frozen_array(self.tool_rotation, (3, 3), "tool_rotation")
        if not (np.allclose(turn @ turn.T, np.eye(3), atol=1e-9) and np.linalg.det(turn) > 0):
            raise ValueError("tool_rotation: not a rotation")
        object.__setattr__(self, "tool_rotation", turn)
        if not (np.isfinite(self.weight_m_per_rad) and self.weight_m_per_rad > 0):
            raise ValueError(f"weight_m_per_rad: {self.weight_m_per_rad}, expected > 0")
        object.__setattr__(self, "weight_m_per_rad", float(self.weight_m_per_rad))

    def places(self, group: str) -> tuple[str, ...]:
        """None: no group is sized by it."""
        return ()

    def document(self) -> dict[str, Any]:
        """The tool's rotation exactly (9 floats, flange_R_tool row by row) and as rx ry rz
        (degrees, R = Rz Ry Rx), and the weight w of an orientation row, m/rad."""
        return {"tool_rotation": self.tool_rotation.ravel().tolist(),
                "tool_rpy_deg": rad_to_deg(angles(self.tool_rotation)).tolist(),
                "weight_m_per_rad": self.weight_m_per_rad}


def pose_part(rig: Rig) -> PoseRig:
    """The rig's :class:`PoseRig` (the flange's orientation and the default weight when it has
    none)."""
    return rig.part if isinstance(rig.part, PoseRig) else PoseRig(np.eye(3))


def pose_measurements(q_rad: ArrayLike, position_m: ArrayLike, rotation_matrix: ArrayLike, *,
                      approach: ArrayLike | None = None) -> Measurements:
    """6-D poses: joint angles (m, n), rad, the tool frame's origin in the instrument's frame
    (m, 3), m, and its orientation instrument_R_tool (m, 3, 3)."""
    return Measurements(np.asarray(q_rad, dtype=np.float64), Pose.name,
                        {POSITION: np.asarray(position_m, dtype=np.float64),
                         ROTATION: np.asarray(rotation_matrix, dtype=np.float64)},
                        approach=None if approach is None else np.asarray(approach))


def _tool(values: Mapping[str, Array], part: PoseRig) -> Array:
    """flange_R_tool of the values, shape (..., 3, 3)."""
    if "tool" not in values:
        return part.tool_rotation
    return np.asarray(part.tool_rotation @ exp_rotation(values["tool"]), dtype=np.float64)


def _frame_rotation(values: Mapping[str, Array], rig: Rig) -> Array:
    """instrument_R_base of the values, shape (..., 3, 3)."""
    nominal = rig.base_in_tracker[:3, :3]
    if "base" not in values:
        return nominal
    return np.asarray(rotation(values["base"][..., 3:]) @ nominal, dtype=np.float64)


def predicted_rotation(at: Measured, values: Mapping[str, Array], rig: Rig) -> Array:
    """What the instrument reads of the tool's orientation, instrument_R_tool, shape
    (..., m, 3, 3)."""
    assert at.rotation is not None
    part = pose_part(rig)
    return np.asarray(_frame_rotation(values, rig)[..., None, :, :] @ at.rotation
                      @ _tool(values, part)[..., None, :, :], dtype=np.float64)


def _rows(at: Measured, values: Mapping[str, Array], data: Measurements, rig: Rig,
          turn_rad: Array) -> Array:
    """The residual rows of :meth:`Pose.residuals` from the orientations' turns
    Log(R_yᵀ R̂), (..., m, 3), rad: shape (..., 6m), m."""
    position = in_instrument(at.position_m, values, rig) - data.value(POSITION)
    rows = np.concatenate([position, pose_part(rig).weight_m_per_rad * turn_rad], axis=-1)
    return np.asarray(rows.reshape(*rows.shape[:-2], -1), dtype=np.float64)


class Pose(Kind):
    """6-D poses (:mod:`twin.kinds.pose`)."""

    name = "pose"
    what = "6-D poses"
    rows_per_pose = 6
    groups = ("base", "tool")
    columns = (*COLUMNS, *QUATERNION)
    unitless = QUATERNION
    columns_text = "x,y,z,qw,qx,qy,qz (mm, unit quaternion)"
    in_instrument_frame = True
    reads_rotation = True
    prediction_note = (" (the tool's orientation in the base frame; then the tool frame in the "
                       "instrument's, mm and unit quaternions)")
    measurement_keys = (*TARGET_KEYS, "sigma_deg", "tool_rpy_deg")
    flags = (("--sigma-deg", "6-D poses (the noise of an orientation)"),)
    point_rows = (0, 1, 2)
    beyond_noun = "orientations"

    def unit_hint(self, rig: Rig, data: Measurements) -> UnitHint | None:
        """Coordinates all within ±10 mm (:func:`twin.kinds.position.coordinates_hint`)."""
        return coordinates_hint(data)

    def template(self, q_rad: Array, rig: Rig, labels: Mapping[str, NDArray[np.intp]]
                 ) -> Measurements:
        """The instrument's origin, unturned."""
        return pose_measurements(q_rad, np.zeros((len(q_rad), 3)),
                                 np.broadcast_to(np.eye(3), (len(q_rad), 3, 3)))

    def residuals(self, at: Measured, values: Mapping[str, Array], data: Measurements,
                  rig: Rig) -> Array:
        """Per pose, x, y, z of the position, then w·Log(R_yᵀ R̂): shape (..., 6m), m."""
        turn = log_rotation(np.swapaxes(data.value(ROTATION), -1, -2)
                            @ predicted_rotation(at, values, rig))
        return _rows(at, values, data, rig, turn)

    def measure(self, at: Measured, values: Mapping[str, Array], template: Measurements,
                rig: Rig) -> Measurements:
        """The poses the model gives, in the instrument's frame."""
        return pose_measurements(template.q_rad, in_instrument(at.position_m, values, rig),
                                 predicted_rotation(at, values, rig), approach=template.approach)

    def jacobian(self, at: Measured, values: Mapping[str, Array], data: Measurements,
                 rig: Rig) -> KindJacobian:
        """Position rows as a tracker's; orientation rows ``w J_l⁻¹(φ) R_yᵀ ω`` for a turn ω
        of the prediction in the instrument's frame: ω = R_ib ω_b for a turn ω_b of the flange
        (base frame), vee(∂R_c/∂a R_cᵀ) for an angle a of the frame's correction,
        R̂ J_r(δ) for the tool's rotation vector δ."""
        m = len(data)
        weight = pose_part(rig).weight_m_per_rad
        measured = data.value(ROTATION)
        predicted = predicted_rotation(at, values, rig)
        phi = log_rotation(np.swapaxes(measured, -1, -2) @ predicted)
        turn = weight * left_jacobian_inverse(phi) @ np.swapaxes(measured, -1, -2)  # (m, 3, 3)
        frame_turn, frame = frame_jacobian(at.position_m, values, rig)
        by_position = np.zeros((m, 6, 3))
        by_position[:, :3] = frame_turn
        by_rotation = np.zeros((m, 6, 3))
        by_rotation[:, 3:] = turn @ _frame_rotation(values, rig)
        by_group: dict[str, Array] = {}
        if frame is not None:
            columns = np.zeros((m, 6, 6))
            columns[:, :3] = frame
            corrected = rotation(values["base"][3:])
            spins = np.stack([_vee(derivative @ corrected.T)
                              for derivative in rotation_derivatives(values["base"][3:])],
                             axis=-1)  # (3, 3): column k the instrument-frame turn of angle k
            columns[:, 3:, 3:] = turn @ spins
            by_group["base"] = columns.reshape(6 * m, 6)
        if "tool" in values:
            columns = np.zeros((m, 6, 3))
            columns[:, 3:] = turn @ predicted @ right_jacobian(values["tool"])
            by_group["tool"] = columns.reshape(6 * m, 3)
        # The rows from the turn φ made here: Log through scipy was a fifth of the Jacobian.
        return KindJacobian(_rows(at, values, data, rig, phi), by_position, by_group,
                            by_rotation)

    def prepare(self, robot: RobotModel, rig: Rig, data: Measurements, noise: Noise
                ) -> tuple[Rig, Measurements]:
        """The rig's pose part: the tool as told (the flange's orientation unless started
        from the data), rows weighted by σ / σ_θ (σ_θ 0.01° when not stated)."""
        sigma_rad = noise.sigma_rad if noise.sigma_rad is not None \
            else float(deg_to_rad(DEFAULT_SIGMA_DEG))
        part = PoseRig(pose_part(rig).tool_rotation, noise.sigma_m / sigma_rad)
        return replace(rig, part=part), data

    def start(self, model: Model, train: Measurements) -> Model:
        """With the frame estimated: its rigid fit to the positions; with the tool estimated:
        its rotation at the chordal mean of what the readings say of it."""
        if model.has("base"):
            model = self.align(model, train)
        if not model.has("tool"):
            return model
        frame = model.rig.base_in_tracker[:3, :3]
        flange = model.robot.flange_transforms(train.q_rad)[:, :3, :3]
        seen = np.swapaxes(frame @ flange, -1, -2) @ train.value(ROTATION)
        part = replace(pose_part(model.rig), tool_rotation=mean_rotation(seen))
        return replace(model, rig=replace(model.rig, part=part))

    def align(self, model: Model, data: Measurements) -> Model:
        """The instrument's frame at the rigid fit of the nominal model's points to the
        positions read."""
        return fit_frame(model, data, data.value(POSITION))

    def predict(self, model: Model, x: Array, poses: Measurements) -> dict[str, Array]:
        """The tool frame's orientation in the base frame (``base_rotation``), and the tool
        frame in the instrument's: its origin and orientation."""
        measured = model.read(x, poses)
        values = {name: model.block(x, name) for name in self.groups if model.has(name)}
        turn = np.swapaxes(_frame_rotation(values, model.rig), -1, -2) @ measured.value(ROTATION)
        return {BASE_ROTATION: turn, POSITION: measured.value(POSITION),
                ROTATION: measured.value(ROTATION)}

    def from_columns(self, q_rad: Array, numbers: Mapping[str, Array],
                     labels: Mapping[str, list[str]], lines: Sequence[int],
                     approach: NDArray[np.int8] | None) -> Measurements:
        """``x,y,z`` in mm and a unit quaternion ``qw,qx,qy,qz`` (normalised within
        :data:`QUATERNION_TOL`)."""
        quaternion = np.stack([numbers[c] for c in QUATERNION], axis=1)
        norm = np.linalg.norm(quaternion, axis=1)
        off = np.flatnonzero(np.abs(norm - 1.0) > QUATERNION_TOL)
        if off.size:
            raise InputError(f"a quaternion of norm {norm[off[0]]:.6g}",
                             f"a unit quaternion qw,qx,qy,qz (within {QUATERNION_TOL:g})",
                             where=f"line {lines[off[0]]}")
        turn = quaternion_rotation(quaternion)
        return pose_measurements(q_rad, read_xyz_mm(numbers, lines), turn, approach=approach)

    def to_columns(self, data: Measurements) -> list[tuple[str, list[str]]]:
        """``x,y,z`` (mm) and ``qw,qx,qy,qz`` (qw ≥ 0)."""
        xyz = m_to_mm(data.value(POSITION))
        quaternion = _quaternions(data.value(ROTATION))
        return [*((name, mm_cells(xyz[:, k])) for k, name in enumerate(COLUMNS)),
                *((name, mm_cells(quaternion[:, k])) for k, name in enumerate(QUATERNION))]

    def prediction_columns(self, predicted: Mapping[str, Array]) -> list[tuple[str, Array]]:
        """``qw,qx,qy,qz`` (the tool's orientation in the base frame, beside its origin x,y,z),
        then the tool frame in the instrument's frame: ``instrument_x,y,z`` (mm) and
        ``instrument_qw,qx,qy,qz``."""
        base = _quaternions(predicted[BASE_ROTATION])
        xyz = m_to_mm(predicted[POSITION])
        quaternion = _quaternions(predicted[ROTATION])
        return [*((name, base[:, k]) for k, name in enumerate(QUATERNION)),
                *((f"instrument_{name}", xyz[:, k]) for k, name in enumerate(COLUMNS)),
                *((f"instrument_{name}", quaternion[:, k]) for k, name in enumerate(QUATERNION))]

    def read_part(self, document: Any) -> Part | None:
        """:meth:`PoseRig.document` back.

        Raises:
            InputError: for a rotation that is not 9 numbers of a rotation matrix, or a weight
                that is not positive.
        """
        turn = document.get("tool_rotation") if isinstance(document, dict) else None
        weight = document.get("weight_m_per_rad") if isinstance(document, dict) else None
        try:
            return PoseRig(np.reshape(np.asarray(turn, dtype=np.float64), (3, 3)),
                           float(weight))  # type: ignore[arg-type]
        except (TypeError, ValueError):
            raise InputError(f"{document!r}", '{"tool_rotation": [9 numbers of a rotation], '
                             '"weight_m_per_rad": w > 0}') from None

    def report(self, model: Model, x: Array) -> list[str]:
        """The identified tool frame's rotation (flange frame), with the tool estimated."""
        if not model.has("tool"):
            return []
        turn = pose_part(model.rig).tool_rotation @ exp_rotation(model.block(x, "tool"))
        shown = ", ".join(f"{v:.4f}" for v in rad_to_deg(angles(turn)))
        return [f"  identified tool rotation (flange frame): rx ry rz ({shown}) deg"]

    def describe(self, rig: Rig, data: Measurements) -> str:
        """``6-D poses``."""
        return "6-D poses (position and orientation of the tool)"

    def draw(self, canvas: Canvas, rig: Rig, data: Measurements, points_m: Array) -> None:
        """Per pose, the tool frame's origin labelled with its reading, and its three axes as
        read (10 cm, in the base frame the rig's frame puts the instrument in)."""
        canvas.marks("measured", points_m,
                     [xyz_mm(position) for position in data.value(POSITION)], MARK_RADIUS_M)
        frame = rig.base_in_tracker[:3, :3]
        axes = np.swapaxes(frame, -1, -2) @ data.value(ROTATION)  # base_R_tool as read
        for k, axis in enumerate("xyz"):
            canvas.lines(f"measured_axes/{axis}", points_m,
                         points_m + AXIS_LENGTH_M * axes[:, :, k], [axis] * len(points_m))

    def read_setup(self, tables: Mapping[str, Fields]) -> PoseSetup:
        """``[measurement]``: the tool frame's origin, the noise of a position (``sigma_mm``) and
        of an angle (``sigma_deg``), the instrument's pose (``tracker_pose``), the tool's true
        rotation (``tool_rpy_deg``); no ``[cable]``, ``[fixture]`` or ``[port]``."""
        target = read_target(tables, self.name, frame=True)
        measurement = tables["measurement"]
        sigma_rad = deg_to_rad(measurement.vector("sigma_deg", 3, per_joint=True, minimum=0.0,
                                                  default=0.0))
        tool = rotation(deg_to_rad(measurement.vector("tool_rpy_deg", 3,
                                                      default=[0.0, 0.0, 0.0])))
        refuse_port(tables, self.name)
        return PoseSetup(target.attachment_m, target.attachment_told_m, target.sigma_m,
                         sigma_rad, target.frame, tool)


AXIS_LENGTH_M = 0.1
"""How long the drawn axes of a pose are, m."""


def _vee(skew_matrix: Array) -> Array:
    """The vector v of [v]× (3, 3)."""
    return np.array([skew_matrix[2, 1], skew_matrix[0, 2], skew_matrix[1, 0]])


def _quaternions(rotations: Array) -> Array:
    """Unit quaternions (m, 4), scalar first and not negative, of rotations (m, 3, 3)."""
    quaternion = rotation_quaternion(rotations)
    return np.where(quaternion[:, :1] < 0, -quaternion, quaternion)


def pose_readings(points_m: Array, flange_rotations: Array, setup: PoseSetup,
                  rng: np.random.Generator) -> tuple[Array, Array]:
    """What the instrument reads of the tool at rest: its origin (m, 3) and orientation
    (m, 3, 3) in the instrument's frame, with N(0, σ²) per axis on the position and a turn of
    N(0, σ_θ²) per axis (a rotation vector, applied on the left) on the orientation."""
    frame = setup.base_in_instrument
    seen = points_m @ frame[:3, :3].T + frame[:3, 3]
    position = seen + rng.normal(0.0, 1.0, seen.shape) * setup.sigma_m
    turned = frame[:3, :3] @ flange_rotations @ setup.tool_rotation
    noise = exp_rotation(rng.normal(0.0, 1.0, (len(points_m), 3)) * setup.sigma_rad)
    return np.asarray(position, dtype=np.float64), np.asarray(noise @ turned, dtype=np.float64)


@dataclass(frozen=True)
class PoseSetup(TargetSetup):
    """A 6-DoF instrument in the twin (:class:`twin.kinds.bench.Setup`): the tool frame at
    rest, carried into the instrument's frame by its true pose and read with Gaussian noise of
    σ per axis on the position and σ_θ per axis on the orientation (:func:`pose_readings`).

    Attributes:
        attachment_m: The true tool frame's origin in the flange frame, shape (3,), m.
        attachment_told_m: The origin the calibration is told, shape (3,), m.
        sigma_m: Position noise 1σ per axis, shape (3,), m.
        sigma_rad: Angle noise 1σ per axis (of a small turn), shape (3,), rad.
        base_in_instrument: The true instrument frame: where the base sits in it, (4, 4), m.
        tool_rotation: The tool frame's true rotation in the flange frame, (3, 3).
    """

    sigma_rad: Array
    base_in_instrument: Array
    tool_rotation: Array

    def __post_init__(self) -> None:
        super().__post_init__()
        for name, shape in (("sigma_rad", (3,)), ("base_in_instrument", (4, 4)),
                            ("tool_rotation", (3, 3))):
            object.__setattr__(self, name, frozen_array(getattr(self, name), shape, name))

    def noise_mm(self, sigma_m: float, resolution_m: float) -> dict[str, float]:
        """The RMS of the per-axis position σ (mm) and angle σ (degrees)."""
        return {"sigma_mm": float(m_to_mm(per_axis_sigma(self.sigma_m))),
                "sigma_deg": float(rad_to_deg(per_axis_sigma(self.sigma_rad)))}

    def rigs(self, rng: np.random.Generator) -> tuple[Rig, Rig]:
        """The true frame and tool; the calibration is told the tool's origin alone (the
        frame it starts at a rigid fit, the tool's rotation at the data's mean)."""
        part = PoseRig(self.tool_rotation)
        return (Rig(attachment_m=self.attachment_m, base_in_tracker=self.base_in_instrument,
                    part=part),
                Rig(attachment_m=self.attachment_told_m))

    def capture(self, bench: Bench, rig: Rig, rng: np.random.Generator) -> Captured:
        """The tool frame at rest at drawn poses, read with noise."""
        visit = bench.visit([None], rng)
        position, turn = pose_readings(visit.rest.point_m, visit.rest.rotation, self, rng)
        data = pose_measurements(visit.q_rad, position, turn,
                                 approach=visit.approach)
        return Captured(data, visit.rest, np.zeros(0, dtype=np.intp), visit.joint_sigma_rad)

    def angle_sigma_rad(self) -> float | None:
        """The RMS of the per-axis angle σ (None when zero: the calibration's default)."""
        sigma = per_axis_sigma(self.sigma_rad)
        return sigma if sigma > 0 else None

    def truth(self, rig: Rig) -> dict[str, Any]:
        """``tracker_pose`` (the instrument's, [x, y, z] mm and [rx, ry, rz] degrees) and
        ``tool_rotation`` (flange_R_tool, 3×3)."""
        frame = self.base_in_instrument
        return {"tracker_pose": [*m_to_mm(frame[:3, 3]).tolist(),
                                 *rad_to_deg(angles(frame[:3, :3])).tolist()],
                "tool_rotation": self.tool_rotation.tolist()}
