"""Robot description: a kinematic table with its parametrisation, joint limits and fixed ends.

A model file is TOML, in mm and degrees (or m and rad, as declared)::

    name = "ABB IRB 120"
    parametrisation = "dh"          # "dh" (default), "mdh", "auto", or one per joint
    length_unit = "mm"
    angle_unit = "deg"
    joints = [
      { a = 0.0, d = 290.0, alpha = -90.0, theta = 0.0, lower = -165.0, upper = 165.0 },
      ...
    ]
    base = { xyz = [0.0, 0.0, 0.0], rpy = [0.0, 0.0, 0.0] }   # optional
    tool = { xyz = [0.0, 0.0, 0.0], rpy = [0.0, 0.0, 0.0] }   # optional

From 4 to 7 joints. ``parametrisation`` says what a joint row means (:mod:`twin.kinematics`):

- ``"dh"``: standard (distal) D-H, joint i contributes ``Rz(q_i + theta_i) · Tz(d_i) · Tx(a_i) ·
  Rx(alpha_i)`` — the paper's form;
- ``"mdh"``: modified D-H (Craig), ``Rx(alpha) · Tx(a) · Rz(q + theta) · Tz(d)``;
- a list of one of ``"dh"``, ``"mdh"``, ``"hayati"`` per joint: each row in its own
  parametrisation; a Hayati row has ``beta`` (an angle) instead of ``d``;
- ``"auto"``: the rows are standard D-H and give the geometry; the model converts them exactly
  (same forward kinematics) to Hayati joints where consecutive axes are nearly parallel and
  standard D-H elsewhere (:mod:`twin.parametrisation`).

``base`` and ``tool`` are fixed transforms (xyz in the length unit, fixed-axis roll–pitch–yaw in
the angle unit, as a URDF origin) before joint 1 and after the last joint's row. Optional
per-joint keys: ``mass`` (kg, of the link after the joint), ``com = [x, y, z]`` (length unit:
that link's centre of mass in its own frame i, which turns with joint i; needs ``mass``) and
``radius`` (length unit, of that link's capsule) for the digital twin and the ``compliance``
unknowns' gravity torques; ``velocity`` (angle unit per second) and ``effort`` (N·m), the
joint's rated limits, for exported URDFs.

A model file may instead name a URDF (:mod:`twin.io.urdf_reader`, through Pinocchio)::

    urdf = "ur5e.urdf"               # relative to this file
    base_link = "base_link"          # optional: the URDF's root link
    tip_link = "tool0"               # optional: tool0, else flange, else the one leaf link
    parametrisation = "auto"         # optional: "auto" (default), "dh", "mdh" or one per joint

and a robot file given as ``--robot arm.urdf`` is read with those defaults.
"""

from __future__ import annotations

import json
import math
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import frozen_array
from twin.errors import InputError
from twin.io.table import Table
from twin.kinematics import (
    PARAMETRISATIONS,
    SLOT_IS_LENGTH,
    SLOT_NAMES,
    Structure,
    fixed_transforms,
    flange_transform,
    point_position,
    rigid_transform,
    xyz_rpy,
)
from twin.parametrisation import AUTO, REQUESTS, check_mix, convert, joint_frames
from twin.units import (
    ANGLE_FACTORS,
    FILE_DEG_DECIMALS,
    FILE_MM_DECIMALS,
    LENGTH_FACTORS,
    MAX_LENGTH_M,
    m_to_mm,
    rad_to_deg,
    rounded,
)

MIN_JOINTS, MAX_JOINTS = 4, 7
"""Joints a model may have: the serial arms twin calibrates (a SCARA-like 4-axis arm to a
7-axis arm)."""
_TOP_KEYS = ("name", "parametrisation", "convention", "length_unit", "angle_unit", "joints",
             "base", "tool")
_LIMIT_KEYS = ("lower", "upper")
_OPTIONAL_JOINT_KEYS = ("mass", "radius", "velocity", "effort")
_COM_KEY = "com"
MAX_ANGLE_RAD = 4 * math.pi
"""Largest |alpha|, |theta| and |joint limit| accepted from a model file: two turns."""
MAX_MASS_KG = 1e4
MAX_VELOCITY_RAD_S = 100.0
"""Largest joint velocity limit accepted from a model file, rad/s (some 950 rpm)."""
MAX_EFFORT_NM = 1e6
"""Largest joint effort limit accepted from a model file, N·m."""


@dataclass(frozen=True)
class UrdfSource:
    """The URDF a robot was read from, kept whole so that a calibration can be written back
    into it (:mod:`twin.export.urdf`) with every name, mesh, inertial and limit.

    Attributes:
        text: The URDF document.
        base_link: The link the chain starts from (the robot's base frame).
        tip_link: The link whose frame is the flange.
        joint_names: The revolute joints of the chain, base to tip, length n.
        frame_offsets: Where each URDF joint's frame (turned so that its axis is z) sits in the
            table's frame of that joint, whose z is the same axis: a shift along it (m) and a
            turn about it (rad), shape (n, 2). Kept so that writing a calibration back moves
            the URDF's link frames (and their meshes and inertials) by the calibration only.
    """

    text: str
    base_link: str
    tip_link: str
    joint_names: tuple[str, ...]
    frame_offsets: NDArray[np.float64]

    def __post_init__(self) -> None:
        offsets = frozen_array(self.frame_offsets, (len(self.joint_names), 2), "frame_offsets")
        object.__setattr__(self, "frame_offsets", offsets)


@dataclass(frozen=True)
class RobotModel:
    """A serial arm: a kinematic table with its structure, joint limits, and what the twin
    and the exports need, SI inside.

    Attributes:
        name: Human-readable name.
        dh: Kinematic table, shape (4, n): slots a [m], d [m] (β [rad] on a Hayati joint),
            alpha [rad], theta offset [rad] (:mod:`twin.kinematics`).
        lower_rad: Lower joint limits, shape (n,), rad.
        upper_rad: Upper joint limits, shape (n,), rad.
        mass_kg: Link masses, shape (n,), kg, or None when the file gives none.
        radius_m: Link capsule radii, shape (n,), m, or None when the file gives none.
        structure: What the table means (parametrisation per joint, base and tool
            transforms); standard D-H with bare ends by default.
        velocity_rad_s: Rated joint speeds, shape (n,), rad/s, or None when unknown.
        effort_nm: Rated joint torques, shape (n,), N·m, or None when unknown.
        urdf: The URDF the robot was read from, or None.
        com_m: Link centres of mass, row i in link i's frame (frame i of the chain, which
            turns with joint i), shape (n, 3), m, or None when the file gives none; needs
            ``mass_kg``.
    """

    name: str
    dh: NDArray[np.float64]
    lower_rad: NDArray[np.float64]
    upper_rad: NDArray[np.float64]
    mass_kg: NDArray[np.float64] | None = field(default=None)
    radius_m: NDArray[np.float64] | None = field(default=None)
    structure: Structure = field(default=None)  # type: ignore[assignment]
    velocity_rad_s: NDArray[np.float64] | None = field(default=None)
    effort_nm: NDArray[np.float64] | None = field(default=None)
    urdf: UrdfSource | None = field(default=None)
    com_m: NDArray[np.float64] | None = field(default=None)

    def __post_init__(self) -> None:
        dh = np.asarray(self.dh, dtype=np.float64)
        if dh.ndim != 2 or dh.shape[0] != 4 or dh.shape[1] < 1:
            raise ValueError(f"dh: shape {dh.shape}, expected (4, n)")
        n = dh.shape[1]
        object.__setattr__(self, "dh", frozen_array(dh, (4, n), "dh"))
        if self.structure is None:
            object.__setattr__(self, "structure", Structure.standard(n))
        if self.structure.n_joints != n:
            raise ValueError(f"structure: {self.structure.n_joints} joints for a table of {n}")
        object.__setattr__(self, "lower_rad", frozen_array(self.lower_rad, (n,), "lower_rad"))
        object.__setattr__(self, "upper_rad", frozen_array(self.upper_rad, (n,), "upper_rad"))
        if np.any(self.lower_rad >= self.upper_rad):
            raise ValueError("joint limits: lower must be below upper")
        for name in ("mass_kg", "radius_m", "velocity_rad_s", "effort_nm"):
            value = getattr(self, name)
            if value is not None:
                array = frozen_array(value, (n,), name)
                if np.any(array < 0):
                    raise ValueError(f"{name}: negative values")
                object.__setattr__(self, name, array)
        if self.urdf is not None and len(self.urdf.joint_names) != n:
            raise ValueError(f"urdf: {len(self.urdf.joint_names)} joint names for {n} joints")
        if self.com_m is not None:
            if self.mass_kg is None:
                raise ValueError("com_m: centres of mass need link masses (mass_kg)")
            object.__setattr__(self, "com_m", frozen_array(self.com_m, (n, 3), "com_m"))

    @property
    def n_joints(self) -> int:
        """Number of joints n."""
        return int(self.dh.shape[1])

    @property
    def is_length(self) -> NDArray[np.bool_]:
        """Whether each table entry is a length (m) rather than an angle (rad), shape (4, n)."""
        return self.structure.is_length

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The joints' names: the URDF's, or ``joint_1``…``joint_n``."""
        if self.urdf is not None:
            return self.urdf.joint_names
        return tuple(f"joint_{i + 1}" for i in range(self.n_joints))

    def perturbed(self, delta: ArrayLike) -> RobotModel:
        """This robot with errors of its table added.

        Args:
            delta: Errors in the table's slot order (δa1..n, δd1..n, δα1..n, δθ1..n for a D-H
                arm), shape (4n,) or (4, n), m and rad.
        """
        delta_rows = np.asarray(delta, dtype=np.float64).reshape(4, self.n_joints)
        return replace(self, dh=self.dh + delta_rows)

    def flange_positions(self, q_rad: ArrayLike) -> NDArray[np.float64]:
        """The flange centre at joint angles q (m, n) rad: shape (m, 3), m, base frame."""
        return point_position(self.structure, self.dh, q_rad)

    def flange_transforms(self, q_rad: ArrayLike) -> NDArray[np.float64]:
        """base_T_flange at joint angles q (m, n) rad: shape (m, 4, 4), m."""
        return flange_transform(self.structure, self.dh, q_rad)

    def reparametrised(self, request: str | Sequence[str]) -> RobotModel:
        """The same arm (same forward kinematics, to 1e-9 m) in another parametrisation:
        ``auto``, one of :data:`twin.kinematics.PARAMETRISATIONS`, or one per joint; a URDF's
        joint frames keep their place (:attr:`UrdfSource.frame_offsets` follow the table)."""
        structure, table = convert(fixed_transforms(self.structure, self.dh), request)
        urdf = self.urdf
        if urdf is not None:
            old = joint_frames(fixed_transforms(self.structure, self.dh))[0]
            new = joint_frames(fixed_transforms(structure, table))[0]
            shift, turn = urdf.frame_offsets.T
            screws = np.zeros((len(shift), 4, 4))
            screws[:, 0, 0] = screws[:, 1, 1] = np.cos(turn)
            screws[:, 1, 0], screws[:, 0, 1] = np.sin(turn), -np.sin(turn)
            screws[:, 2, 2] = screws[:, 3, 3] = 1.0
            screws[:, 2, 3] = shift
            offsets = np.linalg.inv(new) @ old @ screws
            urdf = replace(urdf, frame_offsets=np.column_stack(
                [offsets[:, 2, 3], np.arctan2(offsets[:, 1, 0], offsets[:, 0, 0])]))
        return replace(self, dh=table, structure=structure, urdf=urdf)


def parametrisation_request(table: Table, default: str) -> str | tuple[str, ...]:
    """The ``parametrisation`` key (or the older ``convention``) of a model file: one of
    :data:`twin.parametrisation.REQUESTS`, or one parametrisation per joint."""
    if table.has("parametrisation") and table.has("convention"):
        raise table.error("convention", "both 'parametrisation' and 'convention'",
                          "'parametrisation' alone ('convention' is its older name)")
    key = "convention" if table.has("convention") else "parametrisation"
    value = table.values.get(key, default)
    if key == "convention" and value != "dh":
        raise table.error(key, f"convention {value!r}", "'dh' (standard D-H; other "
                          "parametrisations are named by 'parametrisation')")
    if isinstance(value, str) and value in REQUESTS:
        return value
    if isinstance(value, list) and value and all(v in PARAMETRISATIONS for v in value):
        return tuple(value)
    raise table.error(key, f"{key} = {value!r}", "one of " + ", ".join(REQUESTS)
                      + ", or a list of " + ", ".join(PARAMETRISATIONS) + " per joint")


def _within(unit: str, largest: float) -> str:
    return f"a number within ±{largest:g} {unit}"


def _end_transform(doc: Table, key: str, to_m: float, to_rad: float,
                   units: tuple[str, str]) -> NDArray[np.float64]:
    """The optional ``base`` / ``tool`` table: {xyz = [3 lengths], rpy = [3 angles]}."""
    if not doc.has(key):
        return np.eye(4)
    end = doc.table(key, allowed=("xyz", "rpy"), expected=f"{{ xyz = [x, y, z] ({units[0]}), "
                    f"rpy = [roll, pitch, yaw] ({units[1]}) }}")
    parts = [end.vector(part, 3, within=largest / factor, default=[0.0, 0.0, 0.0],
                        expected=f"[x, y, z]: three numbers in {unit}, each within "
                        f"±{largest / factor:g}") * factor
             for part, factor, largest, unit in (("xyz", to_m, MAX_LENGTH_M, units[0]),
                                                 ("rpy", to_rad, MAX_ANGLE_RAD, units[1]))]
    return rigid_transform(parts[0], parts[1])


def parse_robot(document: dict[str, Any], source: str | Path) -> RobotModel:
    """Validate a parsed model document and build the robot from it.

    Raises:
        InputError: naming the key or joint that is wrong and what was expected.
    """
    if "urdf" in document:
        raise InputError("a 'urdf' reference", "a D-H model file here (twin.io.robot_file."
                         "load_robot reads the files that name a URDF)", source=source)
    doc = Table(document, source, allowed=_TOP_KEYS, kind="or a 'urdf' reference")
    name = doc.text("name")
    length_unit = doc.text("length_unit", choices=tuple(LENGTH_FACTORS))
    angle_unit = doc.text("angle_unit", choices=tuple(ANGLE_FACTORS))
    request = parametrisation_request(doc, "dh")
    joints = doc.required("joints", f"a list of {MIN_JOINTS} to {MAX_JOINTS} joint tables")
    if not isinstance(joints, list) or not MIN_JOINTS <= len(joints) <= MAX_JOINTS:
        count = len(joints) if isinstance(joints, list) else type(joints).__name__
        raise doc.error("joints", f"{count} joints", f"a list of {MIN_JOINTS} to {MAX_JOINTS} "
                        "joint tables")
    n = len(joints)
    if isinstance(request, tuple) and len(request) != n:
        raise doc.error("parametrisation", f"{len(request)} parametrisations for {n} joints",
                        "one per joint")
    # "auto" rows are standard D-H: the geometry the conversion starts from.
    kinds = request if isinstance(request, tuple) else \
        ("dh",) * n if request == AUTO else (request,) * n
    to_m, to_rad = LENGTH_FACTORS[length_unit], ANGLE_FACTORS[angle_unit]
    # key: (factor to SI, largest magnitude in SI, unit as written, smallest value in SI)
    per_unit = {"mass": (1.0, MAX_MASS_KG, "kg", 0.0),
                "radius": (to_m, MAX_LENGTH_M, length_unit, 0.0),
                "velocity": (to_rad, MAX_VELOCITY_RAD_S, f"{angle_unit}/s", 0.0),
                "effort": (1.0, MAX_EFFORT_NM, "N·m", 0.0),
                "lower": (to_rad, MAX_ANGLE_RAD, angle_unit, None),
                "upper": (to_rad, MAX_ANGLE_RAD, angle_unit, None)}
    table = np.zeros((4, n))
    columns: dict[str, list[float]] = {key: [] for key in per_unit}
    coms: list[NDArray[np.float64]] = []
    for index, (values, kind) in enumerate(zip(joints, kinds, strict=True)):
        slots = SLOT_NAMES[kind]
        joint = Table(values, source, f"joint {index + 1}",
                      allowed=(*slots, *_LIMIT_KEYS, *_OPTIONAL_JOINT_KEYS, _COM_KEY),
                      kind=f"a {kind} joint")
        if joint.has(_COM_KEY):
            largest = MAX_LENGTH_M / to_m
            coms.append(joint.vector(_COM_KEY, 3, within=largest, expected=(
                f"[x, y, z]: three numbers in {length_unit}, each within ±{largest:g}")) * to_m)
        for slot, (key, is_length) in enumerate(zip(slots, SLOT_IS_LENGTH[kind], strict=True)):
            factor, largest = (to_m, MAX_LENGTH_M) if is_length else (to_rad, MAX_ANGLE_RAD)
            unit = length_unit if is_length else angle_unit
            joint.required(key, _within(unit, largest / factor))
            table[slot, index] = joint.number(key, minimum=-largest / factor,
                                              maximum=largest / factor,
                                              expected=_within(unit, largest / factor)) * factor
        for key, (factor, largest, unit, smallest) in per_unit.items():
            if key in _LIMIT_KEYS:
                joint.required(key, _within(unit, largest / factor))
            if joint.has(key):
                expected = _within(unit, largest / factor) if smallest is None \
                    else f"a number from 0 to {largest / factor:g} {unit}"
                columns[key].append(joint.number(
                    key, minimum=-largest / factor if smallest is None else smallest,
                    maximum=largest / factor, expected=expected) * factor)
        if columns["lower"][-1] >= columns["upper"][-1]:
            raise joint.error("lower", f"{values['lower']} >= upper = {values['upper']}",
                              "lower < upper")
    optional: dict[str, NDArray[np.float64] | None] = {}
    for key in _OPTIONAL_JOINT_KEYS:
        given = len(columns[key])
        if given not in (0, n):
            raise doc.error("joints", f"{key!r} on {given} of {n} joints",
                            f"{key!r} on every joint or on none")
        optional[key] = np.array(columns[key]) if given else None
    if len(coms) not in (0, n):
        raise doc.error("joints", f"{_COM_KEY!r} on {len(coms)} of {n} joints",
                        f"{_COM_KEY!r} on every joint or on none")
    if coms and optional["mass"] is None:
        raise doc.error("joints", f"{_COM_KEY!r} without 'mass'",
                        "a 'mass' beside every centre of mass")
    units = (length_unit, angle_unit)
    try:
        structure = Structure(kinds, base=_end_transform(doc, "base", to_m, to_rad, units),
                              tool=_end_transform(doc, "tool", to_m, to_rad, units))
        if request == AUTO:
            structure, table = convert(fixed_transforms(structure, table), AUTO)
        else:
            check_mix(kinds)
    except ValueError as exc:
        raise doc.error("parametrisation", str(exc),
                        "a chain the parametrisation can hold") from None
    return RobotModel(
        name=name, dh=table, structure=structure,
        lower_rad=np.array(columns["lower"]), upper_rad=np.array(columns["upper"]),
        mass_kg=optional["mass"], radius_m=optional["radius"],
        velocity_rad_s=optional["velocity"], effort_nm=optional["effort"],
        com_m=np.array(coms) if coms else None,
    )


def default_robot() -> RobotModel:
    """The ABB IRB 120 shipped with the package (the content of `models/irb120.toml`)."""
    resource = resources.files("twin") / "data" / "irb120.toml"
    return parse_robot(tomllib.loads(resource.read_text(encoding="utf-8")), "irb120.toml")


def _end_line(key: str, transform: NDArray[np.float64]) -> str | None:
    if np.allclose(transform, np.eye(4), rtol=0.0, atol=1e-15):
        return None
    xyz, rpy = xyz_rpy(transform)
    return (f"{key} = {{ xyz = {rounded(m_to_mm(xyz), FILE_MM_DECIMALS)!r}, "
            f"rpy = {rounded(rad_to_deg(rpy), FILE_DEG_DECIMALS)!r} }}")


def robot_to_toml(robot: RobotModel) -> str:
    """The model-file text (mm, degrees) of a robot, lengths rounded to 1 µm and angles to
    1e-6 degree (masses to 1 g): numbers a person can read and type. The file reads back to
    exactly the numbers written, and writing it again gives the same bytes.

    Every joint is written in its own parametrisation (``"dh"`` when all are standard D-H,
    else one per joint), with the base and tool transforms when they are not the identity.

    Raises:
        ValueError: for a robot read from a URDF: its file is a reference to the URDF
            (:func:`robot_files`).
    """
    if robot.urdf is not None:
        raise ValueError(f"{robot.name}: a robot read from a URDF is written as a reference "
                         "to it (robot_files)")
    kinds = robot.structure.parametrisation
    request = json.dumps(kinds[0]) if len(set(kinds)) == 1 else json.dumps(list(kinds))
    lines = [
        f"name = {json.dumps(robot.name)}",
        f"parametrisation = {request}",
        'length_unit = "mm"',
        'angle_unit = "deg"',
        "joints = [",
    ]
    display = np.where(robot.is_length, m_to_mm(robot.dh), rad_to_deg(robot.dh))
    decimals = np.where(robot.is_length, FILE_MM_DECIMALS, FILE_DEG_DECIMALS)
    optional = {"lower": rad_to_deg(robot.lower_rad), "upper": rad_to_deg(robot.upper_rad),
                "mass": robot.mass_kg, "radius": None if robot.radius_m is None
                else m_to_mm(robot.radius_m), "velocity": None if robot.velocity_rad_s is None
                else rad_to_deg(robot.velocity_rad_s), "effort": robot.effort_nm}
    places = {"lower": FILE_DEG_DECIMALS, "upper": FILE_DEG_DECIMALS, "mass": 3,
              "radius": FILE_MM_DECIMALS, "velocity": FILE_DEG_DECIMALS, "effort": 3}
    coms = None if robot.com_m is None else np.reshape(
        rounded(m_to_mm(robot.com_m), FILE_MM_DECIMALS), (-1, 3)).tolist()
    for i, kind in enumerate(kinds):
        items = [f"{key} = {rounded([display[slot, i]], int(decimals[slot, i]))[0]!r}"
                 for slot, key in enumerate(SLOT_NAMES[kind])]
        items += [f"{key} = {rounded([values[i]], places[key])[0]!r}"
                  for key, values in optional.items() if values is not None]
        if coms is not None:
            items.append(f"{_COM_KEY} = [{', '.join(map(repr, coms[i]))}]")
        lines.append("  { " + ", ".join(items) + " },")
    lines.append("]")
    lines += [line for key in ("base", "tool")
              if (line := _end_line(key, getattr(robot.structure, key))) is not None]
    return "\n".join(lines) + "\n"


def robot_files(robot: RobotModel, stem: str = "robot") -> dict[str, str]:
    """The files that hold a robot: ``{stem}.toml`` (a model file), and for a robot read from a
    URDF ``{stem}.urdf`` (the URDF as read) with ``{stem}.toml`` naming it, its links and
    its parametrisation, so that reading it back gives the same robot.

    Returns:
        File name to text.
    """
    if robot.urdf is None:
        return {f"{stem}.toml": robot_to_toml(robot)}
    source = robot.urdf
    lines = [
        f"urdf = {json.dumps(f'{stem}.urdf')}",
        f"name = {json.dumps(robot.name)}",
        f"base_link = {json.dumps(source.base_link)}",
        f"tip_link = {json.dumps(source.tip_link)}",
        f"parametrisation = {json.dumps(list(robot.structure.parametrisation))}",
    ]
    return {f"{stem}.toml": "\n".join(lines) + "\n", f"{stem}.urdf": source.text}
