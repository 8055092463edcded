"""How every number a user reads is shown: lengths in mm, angles in degrees (joint-level errors
in arc-seconds), compliances in µrad/(N·m), an encoder's scale in ppm, shares in percent.

:mod:`twin.units` converts between SI and the units people read; this module turns an SI value
into the text a report, a table, a prompt or a message shows, so that how a quantity reads is
decided here and nowhere else. It imports only :mod:`twin.units`: every layer may show a number.

The styles, by what a number is:

- a measured length or error (an RMSE, a noise estimate, a σ): :data:`LENGTH_DECIMALS`, 0.1 µm
  (``0.0093 mm``); an angle :data:`ANGLE_DECIMALS`;
- a position (a port, a measured point, a cable length): :data:`POSITION_DECIMALS`, 1 µm
  (``(600.000, -400.000, 100.000) mm``);
- a figure whose size is not known beforehand (a misfit, a loss scale, a refit): ``significant=``
  :data:`SIGNIFICANT` digits (``18.65 mm``);
- a value echoed as the user gave it (a setting, a limit, a candidate port): ``significant=``
  :data:`AS_GIVEN`, Python's ``g`` (``600``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.units import (
    DISPLAY_UNITS,
    MICRO,
    joint_file_units,
    joints_to_file,
    m_to_mm,
    rad_to_arcsec,
    rad_to_deg,
    to_display,
)

LENGTH_DECIMALS = 4
"""A measured length or error, mm: 0.1 µm, ten times finer than a good encoder resolves."""
POSITION_DECIMALS = 3
"""A position or a cable length, mm: 1 µm, as robot files keep them."""
ANGLE_DECIMALS = 4
"""An angle, degrees: 1e-4 degree, 0.36 arc-second."""
SIGMA_DECIMALS = 5
"""A parameter's standard deviation, mm or degrees: three digits of a σ of some 0.002."""
JOINT_DECIMALS = 2
"""A joint-level error in arc-seconds or µrad/(N·m)."""
JOINT_ANGLE_DECIMALS = 3
"""A joint angle a person jogs to or reads off a pendant, degrees: 1e-3 degree."""
RATIO_DECIMALS = 2
"""A ratio of two figures (an error against its bound)."""
DURATION_DECIMALS = 3
"""A duration, s: 1 ms."""
PPM_DECIMALS = 1
"""A scale error (gain) in parts per million: 0.1 ppm, 0.1 µm over a metre of cable."""
SIGNIFICANT = 4
"""Significant digits of a figure whose size is not known beforehand."""
AS_GIVEN = 6
"""Significant digits of a value echoed as given: Python's ``g``."""


def plain(value: float, decimals: int | None = None, *, significant: int | None = None,
          width: int = 0, sign: bool = False) -> str:
    """``value`` with ``decimals`` fixed decimals, or ``significant`` digits (``g``; the
    default when neither is given, :data:`AS_GIVEN`), right-aligned in ``width`` characters,
    with its sign always shown if ``sign``. A value as wide as its column or wider keeps a
    space before it, so that the columns of a table never run together."""
    kind = f".{decimals}f" if decimals is not None and significant is None \
        else f".{AS_GIVEN if significant is None else significant}g"
    text = format(float(value), f"{'+' if sign else ''}{kind}")
    if text[0] == "-" and not any(digit in "123456789" for digit in text.split("e")[0]):
        # A value rounded to zero has no sign: "-0.0000" (a held α6 at −1e-14) read as an
        # error that had a direction.
        text = ("+" if sign else "") + text[1:]
    return f"{text:>{width}}" if len(text) < width else (" " + text if width else text)


def mm(value_m: ArrayLike, decimals: int = LENGTH_DECIMALS, *,
       significant: int | None = None, width: int = 0, sign: bool = False,
       unit: bool = True) -> str:
    """A length given in m (a number or a 0-d array), in mm: ``0.0093 mm`` (without `` mm``
    if not ``unit``, for a table whose header names it); ``decimals``, ``significant``,
    ``width`` and ``sign`` as in :func:`plain`."""
    text = plain(float(m_to_mm(value_m)), decimals, significant=significant, width=width,
                  sign=sign)
    return f"{text} mm" if unit else text


def mm2(value_m2: float, significant: int = SIGNIFICANT) -> str:
    """A squared length (an objective f, the mean squared residual) given in m², in mm²:
    ``6.84e-06 mm²``."""
    return f"{plain(float(value_m2) * float(m_to_mm(1.0)) ** 2, significant=significant)} mm²"


def mm_values(values_m: ArrayLike, decimals: int = LENGTH_DECIMALS, *,
              significant: int | None = None, separator: str = ", ") -> str:
    """Lengths given in m, in mm, joined by ``separator`` and without the unit:
    ``600, -400, 100`` (``significant=AS_GIVEN``)."""
    return separator.join(plain(v, decimals, significant=significant)
                          for v in np.ravel(m_to_mm(values_m)))


def xyz_mm(values_m: ArrayLike, decimals: int = POSITION_DECIMALS) -> str:
    """A position given in m, shape (3,), in mm: ``(600.000, -400.000, 100.000) mm``."""
    return f"({mm_values(values_m, decimals)}) mm"


def deg(value_rad: ArrayLike, decimals: int = ANGLE_DECIMALS, *,
        significant: int | None = None, width: int = 0, unit: bool = True) -> str:
    """An angle given in rad, in degrees: ``0.0123 deg`` (without `` deg`` if not ``unit``)."""
    text = plain(float(rad_to_deg(value_rad)), decimals, significant=significant,
                  width=width)
    return f"{text} deg" if unit else text


def deg_values(values_rad: ArrayLike, decimals: int = ANGLE_DECIMALS, *,
               separator: str = ", ") -> str:
    """Angles given in rad, in degrees, joined by ``separator`` and without the unit."""
    return separator.join(plain(v, decimals) for v in np.ravel(rad_to_deg(values_rad)))


def joint_values(values_si: ArrayLike, prismatic: ArrayLike, decimals: int = ANGLE_DECIMALS,
                 *, separator: str = ", ") -> tuple[str, str]:
    """Joint values given in SI (rad, m for a prismatic joint), in degrees and mm, joined by
    ``separator`` without units, and the units' label: ``deg``, or ``deg, q1 in mm``."""
    sliding = np.ravel(np.asarray(prismatic, dtype=bool))
    text = separator.join(plain(v, decimals) for v in joints_to_file(values_si, sliding))
    if not sliding.any():
        return text, "deg"
    units = joint_file_units(sliding)
    return text, "deg, " + ",".join(f"q{i + 1}" for i, unit in enumerate(units)
                                    if unit == "mm") + " in mm"


def joint_angles(q_rad: ArrayLike, decimals: int = JOINT_ANGLE_DECIMALS) -> str:
    """Joint angles given in rad, shape (n,), as a person jogs to them: ``[10.000 20.000
    -30.000] deg``."""
    return f"[{deg_values(q_rad, decimals, separator=' ')}] deg"


def seconds(value_s: float, decimals: int = DURATION_DECIMALS) -> str:
    """A duration in seconds: ``0.008 s``."""
    return f"{plain(value_s, decimals)} s"


def elapsed(value: float, timed: bool = True) -> str:
    """A span of a capture: ``3600 s`` (whole seconds), or ``12 rows`` when the rows carry no
    time and their order stands for it."""
    return f"{plain(value, 0)} s" if timed else f"{plain(value, 0)} rows"


def ppm(fraction: float, decimals: int = PPM_DECIMALS, *, sign: bool = True) -> str:
    """A scale error given as a fraction (m/m), in parts per million: ``+98.7 ppm``."""
    return f"{plain(float(fraction) * MICRO, decimals, sign=sign)} ppm"


def slot(value_si: float, is_length: bool, decimals: int | None = None, *,
         width: int = 0) -> str:
    """An entry of a D-H (or Hayati) table given in SI, in its row's unit without it: mm for
    a length, degrees for an angle (``decimals``: :data:`LENGTH_DECIMALS`,
    :data:`ANGLE_DECIMALS`)."""
    if is_length:
        return mm(value_si, LENGTH_DECIMALS if decimals is None else decimals, width=width,
                  unit=False)
    return deg(value_si, ANGLE_DECIMALS if decimals is None else decimals, width=width,
               unit=False)


def joint_level(values_si: ArrayLike, unit: str) -> tuple[NDArray[np.float64], str]:
    """Joint-level values in the unit reports show them in, and its label: angles in
    arc-seconds (what gear makers quote), the rest in the unit results use (µrad/(N·m) for
    compliance, :data:`twin.units.DISPLAY_UNITS`); shown with :data:`JOINT_DECIMALS`."""
    if unit == "rad":
        return rad_to_arcsec(values_si), "arcsec"
    label, factor, _ = DISPLAY_UNITS[unit]
    return np.asarray(values_si, dtype=np.float64) * factor, label


def percent(fraction: float, decimals: int | None = None, *, significant: int | None = None,
            sign: bool = False) -> str:
    """A share given as a fraction, in percent: ``95%`` with ``decimals`` (``+2.5%``), with
    ``significant`` digits (``+0.282%``), or as given (``g``) without either."""
    if decimals is None:
        return f"{plain(100 * fraction, significant=significant, sign=sign)}%"
    return format(float(fraction), f"{'+' if sign else ''}.{decimals}%")


def in_unit(value_si: float, unit: str, significant: int = SIGNIFICANT) -> str:
    """A value in one of the SI units an unknown may have (``m``, ``rad``, ``rad/(N·m)``) in
    the unit results show it in, as results round it (:func:`twin.units.to_display`), with
    ``significant`` digits: ``0.0123 mm``, ``0.5 deg``, ``12.3 µrad/(N·m)``."""
    values, labels = to_display([value_si], [unit])
    return f"{plain(values[0], significant=significant)} {labels[0]}"
