"""The one place where millimetres and degrees meet the SI values used inside.

Everything inside `twin` is in metres and radians. Files, the CLI and reports speak mm and
degrees; they convert here and nowhere else, and numbers written to files are rounded here to
what they mean (:func:`rounded`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

M_PER_MM = 1e-3
LENGTH_FACTORS = {"mm": 1e-3, "m": 1.0}
"""Metres per unit, for the length units accepted in files."""
ANGLE_FACTORS = {"deg": np.pi / 180.0, "rad": 1.0}
"""Radians per unit, for the angle units accepted in files."""


def mm_to_m(value_mm: ArrayLike) -> NDArray[np.float64]:
    """Millimetres to metres."""
    return np.asarray(value_mm, dtype=np.float64) * M_PER_MM


def m_to_mm(value_m: ArrayLike) -> NDArray[np.float64]:
    """Metres to millimetres."""
    return np.asarray(value_m, dtype=np.float64) / M_PER_MM


def deg_to_rad(value_deg: ArrayLike) -> NDArray[np.float64]:
    """Degrees to radians."""
    return np.deg2rad(np.asarray(value_deg, dtype=np.float64))


def rad_to_deg(value_rad: ArrayLike) -> NDArray[np.float64]:
    """Radians to degrees."""
    return np.rad2deg(np.asarray(value_rad, dtype=np.float64))


def joints_from_file(values: ArrayLike, prismatic: ArrayLike | None = None
                     ) -> NDArray[np.float64]:
    """Joint values as files, flags and people give them — degrees, and mm for a prismatic
    joint — to SI (rad, m).

    Args:
        values: Joint values, shape (..., n).
        prismatic: Which joints slide, shape (n,); none if None.
    """
    turned = deg_to_rad(values)
    if prismatic is None or not np.any(prismatic):
        return turned
    return np.asarray(np.where(prismatic, mm_to_m(values), turned), dtype=np.float64)


def joints_to_file(values_si: ArrayLike, prismatic: ArrayLike | None = None
                   ) -> NDArray[np.float64]:
    """Inverse of :func:`joints_from_file`: joint values in SI (rad, m), shape (..., n), to
    degrees and mm."""
    turned = rad_to_deg(values_si)
    if prismatic is None or not np.any(prismatic):
        return turned
    return np.asarray(np.where(prismatic, m_to_mm(values_si), turned), dtype=np.float64)


def joint_file_units(prismatic: ArrayLike) -> tuple[str, ...]:
    """The unit each joint's values have in files: ``deg``, or ``mm`` for a prismatic joint."""
    return tuple("mm" if sliding else "deg" for sliding in np.ravel(prismatic))


ARCSEC_PER_DEG = 3600.0


def rad_to_arcsec(value_rad: ArrayLike) -> NDArray[np.float64]:
    """Radians to arc-seconds: how reports show joint-level errors (gear makers' unit)."""
    return rad_to_deg(value_rad) * ARCSEC_PER_DEG


DH_KEYS = ("a", "d", "alpha", "theta")
"""Row order of a D-H table and of the error vector X (paper eq. 7). In a table of any
parametrisation the rows are its four slots under these keys: a Hayati joint holds its β (an
angle) in the ``d`` row, which ``is_length`` says
(:attr:`twin.geometry.kinematics.Structure.is_length`)."""
DH_IS_LENGTH = (True, True, False, False)


def _row_lengths(rows_si: NDArray[np.float64], is_length: ArrayLike | None) -> NDArray[np.bool_]:
    """Which entries of a (4, n) table are lengths: ``is_length`` (4, n), or D-H's rows."""
    if is_length is None:
        return np.broadcast_to(np.array(DH_IS_LENGTH)[:, None], np.shape(rows_si))
    return np.asarray(is_length, dtype=bool)


def dh_rows_to_display(rows_si: NDArray[np.float64], is_length: ArrayLike | None = None
                       ) -> dict[str, list[float]]:
    """A (4, n) table or error block in SI to ``{"a": [mm], "d": [mm], "alpha": [deg], ...}``;
    with ``is_length`` (4, n) each entry in its own unit (a Hayati β in degrees)."""
    lengths = _row_lengths(rows_si, is_length)
    display = np.where(lengths, m_to_mm(rows_si), rad_to_deg(rows_si))
    return {key: row.tolist() for key, row in zip(DH_KEYS, display, strict=True)}


def dh_rows_from_display(rows: Mapping[str, ArrayLike], is_length: ArrayLike | None = None
                         ) -> NDArray[np.float64]:
    """Inverse of :func:`dh_rows_to_display`: mm/deg dict to a (4, n) block in SI."""
    display = np.stack([np.asarray(rows[key], dtype=np.float64) for key in DH_KEYS])
    lengths = _row_lengths(display, is_length)
    return np.asarray(np.where(lengths, mm_to_m(display), deg_to_rad(display)),
                      dtype=np.float64)


FILE_MM_DECIMALS = 3
"""Robot files and plans: lengths to 1 µm."""
FILE_DEG_DECIMALS = 6
"""Robot files, plans and results: angles to 1e-6 degree (about 1e-8 rad)."""
FILE_JOINT_DECIMALS = 6
"""Plans, corrected programs and predictions: joint values to 1e-6 of their unit (degree, or mm
for a prismatic joint)."""
RESULT_MM_DECIMALS = 6
"""Results: lengths and metrics to 1e-6 mm."""
RESULT_SIGNIFICANT = 6
"""Results: values with a unit of their own (the objective f in mm²), 6 significant digits."""
MAX_LENGTH_M = 1000.0
"""Largest length accepted from a file or flag (a link, a port, a cable, a target), m: every
real one is far shorter, and a 1e300 would overflow the kinematics."""
MAX_LINK_M = 100.0
"""Largest length of a robot's description (a D-H length, a URDF joint's origin, a base or tool
offset, a centre of mass), m: the longest linear tracks a serial arm rides on are tens of
metres; a link of 500 m is a unit mistake that would otherwise calibrate to a MISFIT."""
MAX_ANGLE_RAD = 4 * np.pi
"""Largest angle accepted from a file (a D-H angle, a joint limit, a URDF origin's rpy), rad:
two turns."""


def rounded(values: ArrayLike, decimals: int) -> list[float]:
    """Values rounded to ``decimals`` decimal places, as written to files.

    Python's correctly rounded ``round`` gives floats whose shortest repr has at most that many
    decimals, so a file written from them reads back to exactly these values and writes again
    byte for byte; ``-0.0`` is written as ``0.0``.
    """
    return [round(float(v), decimals) + 0.0 for v in np.ravel(np.asarray(values, dtype=float))]


def dh_rows_rounded(rows_si: NDArray[np.float64], mm_decimals: int,
                    deg_decimals: int = FILE_DEG_DECIMALS, is_length: ArrayLike | None = None
                    ) -> dict[str, list[float]]:
    """:func:`dh_rows_to_display`, rounded as written to a file (lengths to ``mm_decimals``)."""
    lengths = _row_lengths(rows_si, is_length)
    display = dh_rows_to_display(rows_si, lengths)
    return {
        key: [rounded([value], mm_decimals if length else deg_decimals)[0]
              for value, length in zip(values, row, strict=True)]
        for (key, values), row in zip(display.items(), lengths, strict=True)
    }


def significant(value: float, digits: int = RESULT_SIGNIFICANT) -> float:
    """``value`` rounded to ``digits`` significant digits (it reads back exactly, as above)."""
    return float(f"{value:.{digits}g}") + 0.0


COMPLIANCE_UNIT = "rad/(N·m)"
"""SI unit of a joint compliance (deflection per torque, the inverse of a stiffness)."""
LINEAR_COMPLIANCE_UNIT = "m/N"
"""SI unit of a prismatic joint's compliance (travel per axial force)."""
THERMAL_UNIT = "m/K"
"""SI unit of a link's thermal growth: length change per kelvin."""
SCALE_UNIT = "m/m"
"""SI unit of a scale error: a prismatic joint's lead error (travel error per travel), an
encoder's gain error (length error per length; reports show it in ppm, the same µm/m)."""
MICRO = 1e6
RESULT_COMPLIANCE_DECIMALS = 4
"""Results: compliances to 1e-4 µrad/(N·m), far below what a calibration resolves (~0.1)."""

DISPLAY_UNITS: dict[str, tuple[str, float, int]] = {
    "m": ("mm", 1.0 / M_PER_MM, RESULT_MM_DECIMALS),
    # Joint-level angles (transmission error, backlash) read in degrees like the D-H angles
    # they trade with (δθ against a cos q term); 1e-6 degree is 0.0036 arc-second.
    "rad": ("deg", 180.0 / np.pi, FILE_DEG_DECIMALS),
    # An IRB 120 joint is some 1e4–1e6 N·m/rad stiff: 1–100 µrad/(N·m).
    COMPLIANCE_UNIT: ("µrad/(N·m)", MICRO, RESULT_COMPLIANCE_DECIMALS),
    # A lift or a track is some 1e6–1e8 N/m stiff along its axis: 0.01–1 µm/N.
    LINEAR_COMPLIANCE_UNIT: ("µm/N", MICRO, RESULT_COMPLIANCE_DECIMALS),
    # Ball screws and racks are some 10–100 µm per metre of travel off their lead.
    SCALE_UNIT: ("µm/m", MICRO, RESULT_COMPLIANCE_DECIMALS),
    # An aluminium link of 0.3 m grows some 7 µm/K, a steel one 3.5.
    THERMAL_UNIT: ("µm/K", MICRO, RESULT_COMPLIANCE_DECIMALS),
}
"""For each SI unit an unknown may have: the unit people read, the factor to it, and the
decimals a result keeps. An unknown group with a unit of its own adds it here."""


QUANTITY_UNITS: dict[str, tuple[str, float]] = {  # keyed as twin.choices.QUANTITY_UNITS
    "mm": ("m", M_PER_MM), "m": ("m", 1.0),
    "deg": ("rad", np.pi / 180.0), "rad": ("rad", 1.0),
    "arcsec": ("rad", np.pi / (180.0 * ARCSEC_PER_DEG)),
    "urad/Nm": (COMPLIANCE_UNIT, 1.0 / MICRO), "µrad/(N·m)": (COMPLIANCE_UNIT, 1.0 / MICRO),
    "um/N": (LINEAR_COMPLIANCE_UNIT, 1.0 / MICRO), "µm/N": (LINEAR_COMPLIANCE_UNIT, 1.0 / MICRO),
    "um/m": (SCALE_UNIT, 1.0 / MICRO), "µm/m": (SCALE_UNIT, 1.0 / MICRO),
    "um/K": (THERMAL_UNIT, 1.0 / MICRO), "µm/K": (THERMAL_UNIT, 1.0 / MICRO),
    "ppm": (SCALE_UNIT, 1.0 / MICRO),
}
"""The units a value typed with its number may carry (``--bounds a2=20mm``, ``dh=0.5deg``):
for each, the SI unit of the unknowns it applies to and the factor to it."""


def to_display(values_si: ArrayLike, units: tuple[str, ...] | list[str]
               ) -> tuple[list[float], list[str]]:
    """Values in SI units to the units people read (mm, degrees…), rounded as results keep
    them; NaN stays NaN.

    Args:
        values_si: One value per unit, shape (p,).
        units: The SI unit of each value (keys of :data:`DISPLAY_UNITS`).

    Returns:
        ``(values, labels)``: the converted values and their units.
    """
    values, labels = [], []
    for value, unit in zip(np.ravel(np.asarray(values_si, dtype=np.float64)), units,
                           strict=True):
        label, factor, decimals = DISPLAY_UNITS[unit]
        converted = float(value) * factor
        values.append(converted if not np.isfinite(converted) else
                      rounded([converted], decimals)[0])
        labels.append(label)
    return values, labels


def from_display(values: ArrayLike, labels: tuple[str, ...] | list[str]) -> NDArray[np.float64]:
    """Inverse of :func:`to_display`: values in the units people read to SI, shape (p,).

    Raises:
        KeyError: for a unit that is not one of :data:`DISPLAY_UNITS`' display units.
    """
    factors = {label: factor for label, factor, _ in DISPLAY_UNITS.values()}
    return np.asarray(values, dtype=np.float64) / np.array([factors[label] for label in labels])


def display_unit(key: str, is_length: bool | None = None) -> str:
    """``"mm"`` for a, d; ``"deg"`` for alpha, theta (and for a Hayati β in the ``d`` row:
    ``is_length`` False)."""
    length = DH_IS_LENGTH[DH_KEYS.index(key)] if is_length is None else is_length
    return "mm" if length else "deg"


def slot_label(key: str, is_length: ArrayLike) -> str:
    """The column label of a table row ``key`` whose entries are lengths where ``is_length``
    (n,): ``d [mm]``, ``alpha [deg]``, or ``d|beta [mm|deg]`` for a ``d`` row holding Hayati
    β (degrees) beside D-H d (mm)."""
    lengths = np.asarray(is_length, dtype=bool)
    if np.all(lengths):
        return f"{key} [mm]"
    if not np.any(lengths):
        return f"{'beta' if key == 'd' else key} [deg]"
    return f"{key}|beta [mm|deg]"
