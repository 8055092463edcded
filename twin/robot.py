"""Robot description: a standard (distal) Denavit–Hartenberg table with joint limits.

A model file is TOML, in mm and degrees (or m and rad, as declared)::

    name = "ABB IRB 120"
    convention = "dh"
    length_unit = "mm"
    angle_unit = "deg"
    joints = [
      { a = 0.0, d = 290.0, alpha = -90.0, theta = 0.0, lower = -165.0, upper = 165.0 },
      ...
    ]

Joint ``i`` contributes ``Rz(q_i + theta_i) · Tz(d_i) · Tx(a_i) · Rx(alpha_i)``. Optional per-joint
keys: ``mass`` (kg, of the link after the joint), ``com = [x, y, z]`` (length unit: that link's
centre of mass in its own D-H frame i, which turns with joint i) and ``radius`` (length unit, of
that link's capsule). The twin and the ``compliance`` unknowns (gravity torques) use mass and
com; com needs mass.
"""

from __future__ import annotations

import json
import math
import tomllib
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.arrays import frozen_array
from twin.errors import InputError
from twin.io.paths import read_toml
from twin.kinematics import Structure, flange_transform, point_position
from twin.units import (
    ANGLE_FACTORS,
    DH_KEYS,
    FILE_DEG_DECIMALS,
    FILE_MM_DECIMALS,
    LENGTH_FACTORS,
    MAX_LENGTH_M,
    dh_rows_rounded,
    m_to_mm,
    rad_to_deg,
    rounded,
)

N_JOINTS = 6
_TOP_KEYS = ("name", "convention", "length_unit", "angle_unit", "joints")
_REQUIRED_JOINT_KEYS = ("a", "d", "alpha", "theta", "lower", "upper")
_OPTIONAL_JOINT_KEYS = ("mass", "radius")
_COM_KEY = "com"
MAX_ANGLE_RAD = 4 * math.pi
"""Largest |alpha|, |theta| and |joint limit| accepted from a model file: two turns."""
MAX_MASS_KG = 1e4


@dataclass(frozen=True)
class RobotModel:
    """A serial arm: a kinematic table with its structure, joint limits, and what the twin
    needs to build it, SI inside.

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
        for name in ("mass_kg", "radius_m"):
            value = getattr(self, name)
            if value is not None:
                array = frozen_array(value, (n,), name)
                if np.any(array < 0):
                    raise ValueError(f"{name}: negative values")
                object.__setattr__(self, name, array)
        if self.com_m is not None:
            if self.mass_kg is None:
                raise ValueError("com_m: centres of mass need link masses (mass_kg)")
            object.__setattr__(self, "com_m", frozen_array(self.com_m, (n, 3), "com_m"))

    @property
    def n_joints(self) -> int:
        """Number of joints n."""
        return int(self.dh.shape[1])

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


def parse_robot(document: dict[str, Any], source: str | Path) -> RobotModel:
    """Validate a parsed model document and build the robot from it.

    Raises:
        InputError: naming the key or joint that is wrong and what was expected.
    """
    unknown = sorted(set(document) - set(_TOP_KEYS))
    if unknown:
        raise InputError(
            f"unknown key {unknown[0]!r}", "only " + ", ".join(_TOP_KEYS), source=source
        )
    for key in _TOP_KEYS:
        if key not in document:
            raise InputError(f"no {key!r}", f"a {key!r} key", source=source)
    for key in ("name", "convention", "length_unit", "angle_unit"):
        if not isinstance(document[key], str):
            raise InputError(f"{document[key]!r}", "a string", source=source, where=key)
    if document["convention"] != "dh":
        raise InputError(
            f"convention {document['convention']!r}", "'dh' (standard D-H)",
            source=source, where="convention",
        )
    length_unit, angle_unit = document["length_unit"], document["angle_unit"]
    if length_unit not in LENGTH_FACTORS:
        raise InputError(
            f"{length_unit!r}", "one of " + ", ".join(LENGTH_FACTORS),
            source=source, where="length_unit",
        )
    if angle_unit not in ANGLE_FACTORS:
        raise InputError(
            f"{angle_unit!r}", "one of " + ", ".join(ANGLE_FACTORS),
            source=source, where="angle_unit",
        )
    joints = document["joints"]
    if not isinstance(joints, list) or len(joints) != N_JOINTS:
        count = len(joints) if isinstance(joints, list) else type(joints).__name__
        raise InputError(
            f"{count} joints", f"a list of {N_JOINTS} joint tables", source=source,
            where="joints",
        )
    to_m, to_rad = LENGTH_FACTORS[length_unit], ANGLE_FACTORS[angle_unit]
    factor = {"a": to_m, "d": to_m, "alpha": to_rad, "theta": to_rad, "lower": to_rad,
              "upper": to_rad, "mass": 1.0, "radius": to_m}
    # Plausible magnitudes, in SI: every real arm is far inside, and beyond them the
    # kinematics overflows or wraps around.
    largest = {"a": MAX_LENGTH_M, "d": MAX_LENGTH_M, "alpha": MAX_ANGLE_RAD,
               "theta": MAX_ANGLE_RAD, "lower": MAX_ANGLE_RAD, "upper": MAX_ANGLE_RAD,
               "mass": MAX_MASS_KG, "radius": MAX_LENGTH_M}
    columns: dict[str, list[float]] = {key: [] for key in factor}
    coms: list[list[float]] = []
    for index, joint in enumerate(joints, start=1):
        where = f"joint {index}"
        if not isinstance(joint, dict):
            raise InputError(f"{joint!r}", "an inline table", source=source, where=where)
        allowed = (*_REQUIRED_JOINT_KEYS, *_OPTIONAL_JOINT_KEYS, _COM_KEY)
        extra = sorted(set(joint) - set(allowed))
        if extra:
            raise InputError(f"unknown key {extra[0]!r}", "only " + ", ".join(allowed),
                             source=source, where=where)
        if _COM_KEY in joint:
            coms.append(_parse_com(joint[_COM_KEY], to_m, length_unit, source, where))
        for key in factor:
            if key not in joint:
                if key in _REQUIRED_JOINT_KEYS:
                    raise InputError(f"no {key!r}", f"a number for {key!r}",
                                     source=source, where=where)
                continue
            value = joint[key]
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise InputError(f"{key} = {value!r}", "a number", source=source, where=where)
            if not math.isfinite(value):
                raise InputError(f"{key} = {value}", "a finite number", source=source,
                                 where=where)
            if abs(value * factor[key]) > largest[key]:
                unit = "kg" if key == "mass" else length_unit if key in ("a", "d", "radius") \
                    else angle_unit
                raise InputError(f"{key} = {value}", f"a number within "
                                 f"±{largest[key] / factor[key]:g} {unit}", source=source,
                                 where=where)
            columns[key].append(float(value) * factor[key])
        if columns["lower"][-1] >= columns["upper"][-1]:
            raise InputError(
                f"lower = {joint['lower']} >= upper = {joint['upper']}", "lower < upper",
                source=source, where=where,
            )
    optional: dict[str, NDArray[np.float64] | None] = {}
    for key in _OPTIONAL_JOINT_KEYS:
        given = len(columns[key])
        if given not in (0, N_JOINTS):
            raise InputError(f"{key!r} on {given} of {N_JOINTS} joints",
                             f"{key!r} on every joint or on none", source=source)
        if any(v < 0 for v in columns[key]):
            raise InputError(f"a negative {key!r}", "values >= 0", source=source)
        optional[key] = np.array(columns[key]) if given else None
    if len(coms) not in (0, N_JOINTS):
        raise InputError(f"{_COM_KEY!r} on {len(coms)} of {N_JOINTS} joints",
                         f"{_COM_KEY!r} on every joint or on none", source=source)
    if coms and optional["mass"] is None:
        raise InputError(f"{_COM_KEY!r} without 'mass'", "a 'mass' beside every centre of mass",
                         source=source)
    return RobotModel(
        name=str(document["name"]),
        dh=np.array([columns[key] for key in DH_KEYS]),
        lower_rad=np.array(columns["lower"]),
        upper_rad=np.array(columns["upper"]),
        mass_kg=optional["mass"],
        radius_m=optional["radius"],
        com_m=np.array(coms) if coms else None,
    )


def _parse_com(value: Any, to_m: float, length_unit: str, source: str | Path,
               where: str) -> list[float]:
    """A centre of mass ``[x, y, z]`` in the file's length unit, in m."""
    expected = (f"[x, y, z]: three finite numbers in {length_unit}, each within "
                f"±{MAX_LENGTH_M / to_m:g}")
    if not isinstance(value, list) or len(value) != 3 or any(
            isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v)
            or abs(v * to_m) > MAX_LENGTH_M for v in value):
        raise InputError(f"{_COM_KEY} = {value!r}", expected, source=source, where=where)
    return [float(v) * to_m for v in value]


def load_robot(path: str | Path) -> RobotModel:
    """Read and validate a robot model TOML file.

    Raises:
        InputError: if the file is missing, not TOML, or not a valid model.
    """
    path = Path(path)
    return parse_robot(read_toml(path, "a robot model TOML file"), path)


def default_robot() -> RobotModel:
    """The ABB IRB 120 shipped with the package (the content of `models/irb120.toml`)."""
    resource = resources.files("twin") / "data" / "irb120.toml"
    return parse_robot(tomllib.loads(resource.read_text(encoding="utf-8")), "irb120.toml")


def robot_to_toml(robot: RobotModel) -> str:
    """The model-file text (mm, degrees) of a robot, lengths rounded to 1 µm and angles to
    1e-6 degree (masses to 1 g): numbers a person can read and type. The file reads back to
    exactly the numbers written, and writing it again gives the same bytes.

    Raises:
        ValueError: for a structure the D-H file format cannot hold (another parametrisation,
            a base or tool transform).
    """
    if not robot.structure.is_standard:
        raise ValueError(f"{robot.name}: only a standard D-H chain without base or tool "
                         "transform can be written as a D-H model file")
    lines = [
        f"name = {json.dumps(robot.name)}",
        'convention = "dh"',
        'length_unit = "mm"',
        'angle_unit = "deg"',
        "joints = [",
    ]
    columns = dh_rows_rounded(robot.dh, FILE_MM_DECIMALS)
    columns["lower"] = rounded(rad_to_deg(robot.lower_rad), FILE_DEG_DECIMALS)
    columns["upper"] = rounded(rad_to_deg(robot.upper_rad), FILE_DEG_DECIMALS)
    if robot.mass_kg is not None:
        columns["mass"] = rounded(robot.mass_kg, 3)
    if robot.radius_m is not None:
        columns["radius"] = rounded(m_to_mm(robot.radius_m), FILE_MM_DECIMALS)
    coms = None if robot.com_m is None else np.reshape(
        rounded(m_to_mm(robot.com_m), FILE_MM_DECIMALS), (-1, 3)).tolist()
    for i in range(robot.n_joints):
        items = [f"{key} = {values[i]!r}" for key, values in columns.items()]
        if coms is not None:
            items.append(f"{_COM_KEY} = [{', '.join(map(repr, coms[i]))}]")
        lines.append("  { " + ", ".join(items) + " },")
    lines.append("]")
    return "\n".join(lines) + "\n"
