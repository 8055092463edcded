"""The one place where millimetres and degrees meet the SI values used inside.

Everything inside `twin` is in metres and radians. Files, the CLI and reports speak mm and
degrees; they convert here and nowhere else.
"""

from __future__ import annotations

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


DH_KEYS = ("a", "d", "alpha", "theta")
"""Row order of a D-H table and of the error vector X (paper eq. 7)."""
DH_IS_LENGTH = (True, True, False, False)


def dh_rows_to_display(rows_si: NDArray[np.float64]) -> dict[str, list[float]]:
    """A (4, n) table or error block in SI to ``{"a": [mm], "d": [mm], "alpha": [deg], ...}``."""
    return {
        key: (m_to_mm(row) if is_length else rad_to_deg(row)).tolist()
        for key, row, is_length in zip(DH_KEYS, rows_si, DH_IS_LENGTH, strict=True)
    }


def dh_rows_from_display(rows: dict[str, ArrayLike]) -> NDArray[np.float64]:
    """Inverse of :func:`dh_rows_to_display`: mm/deg dict to a (4, n) block in SI."""
    return np.stack(
        [
            mm_to_m(rows[key]) if is_length else deg_to_rad(rows[key])
            for key, is_length in zip(DH_KEYS, DH_IS_LENGTH, strict=True)
        ]
    )


def display_unit(key: str) -> str:
    """``"mm"`` for a, d; ``"deg"`` for alpha, theta."""
    return "mm" if DH_IS_LENGTH[DH_KEYS.index(key)] else "deg"
