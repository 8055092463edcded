"""Reading and writing a robot's file: the one place that knows both formats.

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

From 4 to 9 joints (:data:`twin.choices.MAX_JOINTS`). ``parametrisation`` says what a joint row
means (:mod:`twin.geometry.kinematics`):

- ``"dh"``: standard (distal) D-H, joint i contributes ``Rz(q_i + theta_i) · Tz(d_i) · Tx(a_i) ·
  Rx(alpha_i)`` — the paper's form;
- ``"mdh"``: modified D-H (Craig), ``Rx(alpha) · Tx(a) · Rz(q + theta) · Tz(d)``;
- a list of one of ``"dh"``, ``"mdh"``, ``"hayati"`` per joint: each row in its own
  parametrisation; a Hayati row has ``beta`` (an angle) instead of ``d``;
- ``"auto"``: the rows are standard D-H and give the geometry; the model converts them exactly
  (same forward kinematics) to Hayati joints where consecutive axes are nearly parallel and
  standard D-H elsewhere (:mod:`twin.geometry.parametrisation`).

``base`` and ``tool`` are fixed transforms (xyz in the length unit, fixed-axis roll–pitch–yaw in
the angle unit, as a URDF origin) before joint 1 and after the last joint's row. Optional
per-joint keys: ``type`` (``"revolute"``, the default, or ``"prismatic"``: the joint slides along
its axis, its q adding to d — :mod:`twin.geometry.kinematics` —, and its ``lower``, ``upper``
are lengths in the length unit, its ``velocity`` in length unit per second, its ``effort`` a
force in N); ``mass`` (kg, of the link after the joint), ``com = [x, y, z]`` (length unit:
that link's centre of mass in its own frame i, which moves with joint i; needs ``mass``) and
``radius`` (length unit, of that link's capsule) for the digital twin and the ``compliance``
unknowns' gravity torques; ``velocity`` (angle unit per second) and ``effort`` (N·m), the
joint's rated limits, for exported URDFs.

A model file may instead name a URDF (:mod:`twin.io.urdf_reader`, through Pinocchio)::

    urdf = "ur5e.urdf"               # relative to this file (or a .xacro, with
                                     # xacro_args = { name = "value" })
    base_link = "base_link"          # optional: the URDF's root link
    tip_link = "tool0"               # optional: tool0, else flange, else the one leaf link
    parametrisation = "auto"         # optional: "auto" (default), "dh", "mdh" or one per joint

and a robot file given as ``--robot arm.urdf`` is read with those defaults; ``--robot
arm.urdf.xacro`` (with ``--xacro-arg NAME:=VALUE``) is expanded by xacro first
(:mod:`twin.io.xacro_reader`).

The model is :class:`twin.robot.RobotModel`; the URDF adapter :mod:`twin.io.urdf_reader`.
"""

from __future__ import annotations

import hashlib
import json
import tomllib
from collections.abc import Mapping
from dataclasses import replace
from importlib import resources
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from twin.choices import MAX_JOINTS, MIN_JOINTS
from twin.errors import InputError
from twin.geometry.kinematics import (
    JOINT_TYPES,
    PARAMETRISATIONS,
    SLOT_IS_LENGTH,
    SLOT_NAMES,
    Structure,
    fixed_transforms,
    rigid_transform,
    xyz_rpy,
)
from twin.geometry.parametrisation import AUTO_PARAMETRISATION, REQUESTS, check_mix, convert
from twin.io.paths import read_toml
from twin.io.table import Table
from twin.io.urdf_reader import load_urdf
from twin.io.xacro_reader import XACRO_SUFFIX, expand_xacro
from twin.robot import RobotModel
from twin.units import (
    ANGLE_FACTORS,
    FILE_DEG_DECIMALS,
    FILE_MM_DECIMALS,
    LENGTH_FACTORS,
    MAX_ANGLE_RAD,
    MAX_LINK_M,
    joints_to_file,
    m_to_mm,
    rad_to_deg,
    rounded,
)

URDF_KEYS = ("name", "urdf", "base_link", "tip_link", "parametrisation", "xacro_args")
"""The keys of a model file that names a URDF."""


def _urdf_reference(document: dict[str, Any], source: str | Path) -> RobotModel:
    """A model file that names a URDF: read the URDF with the file's links and parametrisation."""
    doc = Table(document, source, allowed=URDF_KEYS, kind="a model file that names a URDF")
    links = {key: doc.text(key) if doc.has(key) else None for key in ("base_link", "tip_link")}
    path = Path(source).parent / doc.text("urdf")
    text = None
    if path.suffix.lower() == XACRO_SUFFIX:
        arguments = doc.table("xacro_args", expected="{ NAME = \"VALUE\", … }") \
            if doc.has("xacro_args") else None
        text = expand_xacro(path, {key: arguments.text(key) for key in arguments.values}
                            if arguments is not None else {})
    elif doc.has("xacro_args"):
        raise doc.error("xacro_args", "xacro_args for a URDF", "them for a .xacro only")
    robot = load_urdf(path, base_link=links["base_link"], tip_link=links["tip_link"],
                      parametrisation=parametrisation_request(doc, AUTO_PARAMETRISATION), text=text)
    return replace(robot, name=doc.text("name")) if doc.has("name") else robot


def load_robot(path: str | Path, *, base_link: str | None = None, tip_link: str | None = None,
               xacro_args: Mapping[str, str] | None = None) -> RobotModel:
    """Read and validate a robot model: a TOML model file, a URDF (``.urdf``) or a xacro
    description (``.xacro``, expanded by :mod:`twin.io.xacro_reader` with ``xacro_args``).

    Args:
        path: The file.
        base_link: For a URDF: the link the chain starts from (default: the root).
        tip_link: For a URDF: the flange link (default: tool0, flange or the one leaf).
        xacro_args: For a xacro: its arguments, NAME to VALUE.

    Raises:
        InputError: if the file is missing, not TOML (or URDF, or xacro), or not a valid model.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if xacro_args and suffix != XACRO_SUFFIX:
        raise InputError("--xacro-arg with a robot that is not a .xacro", "it with --robot "
                         "ARM.urdf.xacro", source="--xacro-arg")
    if suffix == XACRO_SUFFIX:
        return load_urdf(path, base_link=base_link, tip_link=tip_link,
                         text=expand_xacro(path, xacro_args or {}))
    if suffix == ".urdf":
        return load_urdf(path, base_link=base_link, tip_link=tip_link)
    if base_link is not None or tip_link is not None:
        raise InputError("--base-link or --tip-link with a model TOML file",
                         "them with a URDF (the TOML file names its links itself)",
                         source=path)
    document = read_toml(path, "a robot model TOML file")
    if "urdf" in document:
        return _urdf_reference(document, path)
    return parse_robot(document, path)


def load_robot_or_default(path: str | Path | None, *, base_link: str | None = None,
                          tip_link: str | None = None,
                          xacro_args: Mapping[str, str] | None = None) -> RobotModel:
    """The robot of a file (:func:`load_robot`), or the packaged ABB IRB 120 without one.

    Raises:
        InputError: as :func:`load_robot`.
    """
    if path is None:
        if xacro_args:
            raise InputError("--xacro-arg without --robot", "--robot ARM.urdf.xacro beside it",
                             source="--xacro-arg")
        return default_robot()
    return load_robot(path, base_link=base_link, tip_link=tip_link, xacro_args=xacro_args)

_TOP_KEYS = ("name", "parametrisation", "convention", "length_unit", "angle_unit", "joints",
             "base", "tool")
_LIMIT_KEYS = ("lower", "upper")
_OPTIONAL_JOINT_KEYS = ("mass", "radius", "velocity", "effort")
_COM_KEY = "com"
_TYPE_KEY = "type"
MAX_MASS_KG = 1e4
MAX_VELOCITY_RAD_S = 100.0
"""Largest joint velocity limit accepted from a model file, rad/s (some 950 rpm)."""
MAX_EFFORT_NM = 1e6
"""Largest joint effort limit accepted from a model file, N·m (N on a prismatic joint)."""
MAX_SPEED_M_S = 100.0
"""Largest velocity limit of a prismatic joint accepted from a model file, m/s."""


def parametrisation_request(table: Table, default: str) -> str | tuple[str, ...]:
    """The ``parametrisation`` key (or the older ``convention``) of a model file: one of
    :data:`twin.geometry.parametrisation.REQUESTS`, or one parametrisation per joint."""
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
             for part, factor, largest, unit in (("xyz", to_m, MAX_LINK_M, units[0]),
                                                 ("rpy", to_rad, MAX_ANGLE_RAD, units[1]))]
    return rigid_transform(parts[0], parts[1])


class _Units(NamedTuple):
    """A model file's units as written (``length_unit``, ``angle_unit``)."""

    length: str
    angle: str

    @property
    def to_m(self) -> float:
        """Metres per length unit."""
        return LENGTH_FACTORS[self.length]

    @property
    def to_rad(self) -> float:
        """Radians per angle unit."""
        return ANGLE_FACTORS[self.angle]

    def limits(self, prismatic: bool = False) -> dict[str, tuple[float, float, str, float | None]]:
        """Each per-joint key beside the table's: (factor to SI, largest magnitude in SI, unit
        as written, smallest value in SI or None for ±largest); a prismatic joint's limits
        and speed are lengths, its effort a force."""
        travel = (self.to_m, MAX_LINK_M, self.length, None) if prismatic \
            else (self.to_rad, MAX_ANGLE_RAD, self.angle, None)
        return {"mass": (1.0, MAX_MASS_KG, "kg", 0.0),
                "radius": (self.to_m, MAX_LINK_M, self.length, 0.0),
                "velocity": (self.to_m, MAX_SPEED_M_S, f"{self.length}/s", 0.0) if prismatic
                else (self.to_rad, MAX_VELOCITY_RAD_S, f"{self.angle}/s", 0.0),
                "effort": (1.0, MAX_EFFORT_NM, "N" if prismatic else "N·m", 0.0),
                "lower": travel, "upper": travel}


class _Joint(NamedTuple):
    """One joint table of a model file, in SI."""

    slots: NDArray[np.float64]
    """Its column of the parameter table, shape (4,), m and rad."""
    values: dict[str, float]
    """Its limits and the optional keys given (mass, radius, velocity, effort)."""
    com_m: NDArray[np.float64] | None
    """Its centre of mass, shape (3,), m, if given."""
    joint_type: str
    """``revolute`` or ``prismatic``."""


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
    units = _Units(doc.text("length_unit", choices=tuple(LENGTH_FACTORS)),
                   doc.text("angle_unit", choices=tuple(ANGLE_FACTORS)))
    request = parametrisation_request(doc, "dh")
    joints, kinds = _joint_kinds(doc, request)
    read = [_joint(values, index, kind, source, units)
            for index, (values, kind) in enumerate(zip(joints, kinds, strict=True))]
    optional = _optional_columns(doc, read)
    structure, table = _structure(doc, kinds, request, np.stack([j.slots for j in read], axis=1),
                                  units, tuple(j.joint_type for j in read))
    return RobotModel(
        name=name, dh=table, structure=structure,
        lower_rad=np.array([j.values["lower"] for j in read]),
        upper_rad=np.array([j.values["upper"] for j in read]),
        mass_kg=optional["mass"], radius_m=optional["radius"],
        velocity_rad_s=optional["velocity"], effort_nm=optional["effort"],
        com_m=optional[_COM_KEY],
    )


def _joint_kinds(doc: Table, request: str | tuple[str, ...]
                 ) -> tuple[list[Any], tuple[str, ...]]:
    """The ``joints`` list and each joint's parametrisation (``auto`` rows are standard D-H:
    the geometry the conversion starts from)."""
    joints = doc.required("joints", f"a list of {MIN_JOINTS} to {MAX_JOINTS} joint tables")
    if not isinstance(joints, list) or not MIN_JOINTS <= len(joints) <= MAX_JOINTS:
        count = len(joints) if isinstance(joints, list) else type(joints).__name__
        raise doc.error("joints", f"{count} joints", f"a list of {MIN_JOINTS} to {MAX_JOINTS} "
                        "joint tables")
    n = len(joints)
    if isinstance(request, tuple) and len(request) != n:
        raise doc.error("parametrisation", f"{len(request)} parametrisations for {n} joints",
                        "one per joint")
    kinds = request if isinstance(request, tuple) else \
        ("dh",) * n if request == AUTO_PARAMETRISATION else (request,) * n
    return joints, kinds


def _joint(values: Any, index: int, kind: str, source: str | Path, units: _Units) -> _Joint:
    """Joint ``index`` (0-based) of ``kind``: its type, its centre of mass, its table slots,
    its limits and optional keys, in that order of checking."""
    slots = SLOT_NAMES[kind]
    joint = Table(values, source, f"joint {index + 1}",
                  allowed=(_TYPE_KEY, *slots, *_LIMIT_KEYS, *_OPTIONAL_JOINT_KEYS, _COM_KEY),
                  kind=f"a {kind} joint")
    joint_type = joint.text(_TYPE_KEY, "revolute", choices=JOINT_TYPES)
    com_m = None
    if joint.has(_COM_KEY):
        largest = MAX_LINK_M / units.to_m
        com_m = joint.vector(_COM_KEY, 3, within=largest, expected=(
            f"[x, y, z]: three numbers in {units.length}, each within ±{largest:g}")) * units.to_m
    column = np.zeros(4)
    for slot, (key, is_length) in enumerate(zip(slots, SLOT_IS_LENGTH[kind], strict=True)):
        factor, largest = (units.to_m, MAX_LINK_M) if is_length \
            else (units.to_rad, MAX_ANGLE_RAD)
        unit = units.length if is_length else units.angle
        joint.required(key, _within(unit, largest / factor))
        column[slot] = joint.number(key, minimum=-largest / factor, maximum=largest / factor,
                                    expected=_within(unit, largest / factor)) * factor
    given = {}
    for key, (factor, largest, unit, smallest) in units.limits(joint_type == "prismatic").items():
        if key in _LIMIT_KEYS:
            joint.required(key, _within(unit, largest / factor))
        if joint.has(key):
            expected = _within(unit, largest / factor) if smallest is None \
                else f"a number from 0 to {largest / factor:g} {unit}"
            given[key] = joint.number(
                key, minimum=-largest / factor if smallest is None else smallest,
                maximum=largest / factor, expected=expected) * factor
    if given["lower"] >= given["upper"]:
        raise joint.error("lower", f"{values['lower']} >= upper = {values['upper']}",
                          "lower < upper")
    return _Joint(column, given, com_m, joint_type)


def _optional_columns(doc: Table, joints: list[_Joint]
                      ) -> dict[str, NDArray[np.float64] | None]:
    """Each optional key (and ``com``) over the joints, or None: on every joint or on none,
    and a centre of mass only with masses."""
    n = len(joints)
    optional: dict[str, NDArray[np.float64] | None] = {}
    for key in _OPTIONAL_JOINT_KEYS:
        column = [j.values[key] for j in joints if key in j.values]
        if len(column) not in (0, n):
            raise doc.error("joints", f"{key!r} on {len(column)} of {n} joints",
                            f"{key!r} on every joint or on none")
        optional[key] = np.array(column) if column else None
    coms = [j.com_m for j in joints if j.com_m is not None]
    if len(coms) not in (0, n):
        raise doc.error("joints", f"{_COM_KEY!r} on {len(coms)} of {n} joints",
                        f"{_COM_KEY!r} on every joint or on none")
    if coms and optional["mass"] is None:
        raise doc.error("joints", f"{_COM_KEY!r} without 'mass'",
                        "a 'mass' beside every centre of mass")
    optional[_COM_KEY] = np.array(coms) if coms else None
    return optional


def _structure(doc: Table, kinds: tuple[str, ...], request: str | tuple[str, ...],
               table: NDArray[np.float64], units: _Units, joint_types: tuple[str, ...]
               ) -> tuple[Structure, NDArray[np.float64]]:
    """The chain with the file's ``base`` and ``tool``, and its table; an ``auto`` request
    converted to the parametrisation each joint needs."""
    names = (units.length, units.angle)
    try:
        structure = Structure(
            kinds, base=_end_transform(doc, "base", units.to_m, units.to_rad, names),
            tool=_end_transform(doc, "tool", units.to_m, units.to_rad, names),
            joint_types=joint_types)
        if request == AUTO_PARAMETRISATION:
            return convert(fixed_transforms(structure, table), AUTO_PARAMETRISATION,
                           joint_types)
        check_mix(kinds)
    except ValueError as exc:
        raise doc.error("parametrisation", str(exc),
                        "a chain the parametrisation can hold") from None
    return structure, table


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
    sliding = robot.prismatic
    travel = np.where(sliding, FILE_MM_DECIMALS, FILE_DEG_DECIMALS)
    optional = {"lower": joints_to_file(robot.lower_rad, sliding),
                "upper": joints_to_file(robot.upper_rad, sliding),
                "mass": robot.mass_kg, "radius": None if robot.radius_m is None
                else m_to_mm(robot.radius_m), "velocity": None if robot.velocity_rad_s is None
                else joints_to_file(robot.velocity_rad_s, sliding), "effort": robot.effort_nm}
    places = {"lower": travel, "upper": travel, "mass": np.full(robot.n_joints, 3),
              "radius": np.full(robot.n_joints, FILE_MM_DECIMALS), "velocity": travel,
              "effort": np.full(robot.n_joints, 3)}
    coms = None if robot.com_m is None else np.reshape(
        rounded(m_to_mm(robot.com_m), FILE_MM_DECIMALS), (-1, 3)).tolist()
    for i, kind in enumerate(kinds):
        items = ['type = "prismatic"'] if sliding[i] else []
        items += [f"{key} = {rounded([display[slot, i]], int(decimals[slot, i]))[0]!r}"
                  for slot, key in enumerate(SLOT_NAMES[kind])]
        items += [f"{key} = {rounded([values[i]], int(places[key][i]))[0]!r}"
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


def robot_digest(robot: RobotModel) -> str:
    """The SHA-256 of the robot's description as twin writes it (:func:`robot_files`): two
    files that describe the same robot to the file's rounding have the same digest."""
    files = robot_files(robot)
    text = "".join(f"{name}\n{len(content)}\n{content}" for name, content in sorted(files.items()))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def robot_from_files(files: Mapping[str, str], source: str | Path) -> RobotModel:
    """The robot :func:`robot_files` wrote (``robot.toml``, and ``robot.urdf`` when the TOML
    names it), read from their texts.

    Raises:
        InputError: naming ``source`` for texts that are not such files.
    """
    toml_name = next((name for name in files if name.endswith(".toml")), None)
    if toml_name is None or not isinstance(files[toml_name], str):
        raise InputError("no robot TOML among the robot's files", "the files twin writes "
                         "with a result (robot.toml, and robot.urdf for a URDF robot)",
                         source=source)
    try:
        document = tomllib.loads(files[toml_name])
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"invalid TOML ({exc})", "the robot TOML twin writes",
                         source=source) from None
    if "urdf" not in document:
        return parse_robot(document, source)
    doc = Table(document, source, allowed=URDF_KEYS, kind="a model file that names a URDF")
    urdf = files.get(doc.text("urdf"))
    if not isinstance(urdf, str):
        raise InputError(f"no {doc.text('urdf')!r} beside the robot TOML", "the URDF it names",
                         source=source)
    links = {key: doc.text(key) if doc.has(key) else None for key in ("base_link", "tip_link")}
    robot = load_urdf(source, base_link=links["base_link"], tip_link=links["tip_link"],
                      parametrisation=parametrisation_request(doc, AUTO_PARAMETRISATION), text=urdf)
    return replace(robot, name=doc.text("name")) if doc.has("name") else robot
