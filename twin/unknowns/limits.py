"""What may move and how far: the user's search box, priors and fixed parameters, as rules
over the unknowns' names, resolved against a calibration's groups (:func:`restrict`).

A rule selects unknowns by

- their name (``a2``, ``theta6``, ``port_x``, ``offset``),
- their family, the name without its joint number (``a`` for a1…an, ``theta``, ``sin_q``),
- their group (``dh``, ``transmission``, ``port``…, :data:`twin.unknowns.GROUPS`),

and, for bounds and priors, by the dimension of the value: ``dh=20mm`` bounds the table's
lengths, ``dh=10deg`` its angles. Rules apply in the order given, a later one overriding an
earlier one on the unknowns they share (``dh=10mm,a2=50mm``: every length ±10 mm, a2 ±50 mm).

- **bound** ``SELECT=W`` (±W around the nominal) or ``SELECT=LOW:HIGH``, with its unit: the
  search box every method keeps to. It must hold the nominal (0), where every method starts
  and where what the data cannot see is held. The default is each group's own (the paper's
  ±5 mm / ±8° for the D-H table).
- **prior** ``SELECT=σ``: a zero-mean Gaussian N(0, σ²) around the nominal — Tikhonov
  regularisation, the rows ``x_i / σ_i`` appended to the residuals (method-notes §7,
  :class:`twin.problem.Problem`). It keeps a problem well posed without a hard box; the
  report names the unknowns it, not the data, decided.
- **fix** ``SELECT``: held at the nominal, and left out of the unknowns. A measurement's
  unknowns (ports, offset, tracker frame, fixed points) are fixed as a whole, by not
  estimating them.

Values accept the units of :data:`twin.units.QUANTITY_UNITS` (mm, m, deg, rad, arcsec,
urad/Nm; um/N and um/m for a prismatic joint's compliance and scale).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from twin.errors import InputError
from twin.units import (
    COMPLIANCE_UNIT,
    DISPLAY_UNITS,
    LINEAR_COMPLIANCE_UNIT,
    QUANTITY_UNITS,
    SCALE_UNIT,
    THERMAL_UNIT,
)
from twin.unknowns.group import Group, Stage

LARGEST = {"m": 10.0, "rad": math.pi, COMPLIANCE_UNIT: 1.0, LINEAR_COMPLIANCE_UNIT: 1.0,
           SCALE_UNIT: 1.0, THERMAL_UNIT: 1e-3}
"""The widest bound or prior of each SI unit: 10 m, 180°, 1 rad/(N·m), 1 m/N, 1 m/m, 1 mm/K —
beyond any real error; a wider one is a typo."""
TYPED = {COMPLIANCE_UNIT: "urad/Nm", LINEAR_COMPLIANCE_UNIT: "um/N", SCALE_UNIT: "um/m",
         THERMAL_UNIT: "um/K"}
"""How a rule's text writes the units whose display form is awkward to type."""
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_VALUE = re.compile(rf"^({_NUMBER})(?::({_NUMBER}))?\s*(\S+)$")
_SELECT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
UNITS_TEXT = ", ".join(QUANTITY_UNITS)
"""The units a rule's value may carry, for messages."""


def _quantity(text: str, value: str, unit: str) -> tuple[float, str]:
    """A number and its unit as (SI value, SI unit)."""
    if unit not in QUANTITY_UNITS:
        raise InputError(repr(text), f"a value with one of the units {UNITS_TEXT}")
    si, factor = QUANTITY_UNITS[unit]
    return float(value) * factor, si


def _split(text: str, expected: str) -> tuple[str, str]:
    select, sign, value = text.partition("=")
    select, value = select.strip(), value.strip()
    if not sign or not _SELECT.match(select) or not value:
        raise InputError(repr(text), f"SELECT=VALUE: {expected}")
    return select, value


def _number(value_si: float, unit: str) -> str:
    """A value in the unit people read, as a rule's text writes it (12 significant digits)."""
    return f"{float(f'{value_si * DISPLAY_UNITS[unit][1]:.12g}'):.12g}"


def _suffix(unit: str) -> str:
    """The unit a rule's text writes values of the SI unit ``unit`` in."""
    return TYPED.get(unit, DISPLAY_UNITS[unit][0])


def _rule(text: str, where: str, expected: str) -> tuple[str, float, float | None, str]:
    """A rule's text ``SELECT=V`` or ``SELECT=V1:V2`` with a unit: the selector, V (or V1) and
    V2 (None without) in SI, and the SI unit.

    Raises:
        InputError: naming the text and ``expected`` (``where`` the setting).
    """
    try:
        select, value = _split(text, expected)
        match = _VALUE.match(value)
        if match is None:
            raise InputError(repr(text), expected)
        first, unit = _quantity(text, match[1], match[3])
        second = None if match[2] is None else _quantity(text, match[2], match[3])[0]
        return select, first, second, unit
    except InputError as exc:
        raise InputError(exc.found, exc.expected, where=where) from None


def _shown(value_si: float, unit: str) -> str:
    return _number(value_si, unit) + _suffix(unit)


@dataclass(frozen=True)
class Bound:
    """A search box for the unknowns ``select`` names of the unit ``unit``.

    Attributes:
        select: A name, family or group (module docstring).
        unit: The SI unit of the unknowns it applies to (``m``, ``rad``, ``rad/(N·m)``).
        lower: Lower bound, in ``unit``, <= 0.
        upper: Upper bound, in ``unit``, >= 0 and > lower.
    """

    select: str
    unit: str
    lower: float
    upper: float

    def __post_init__(self) -> None:
        widest = LARGEST.get(self.unit, 0.0)
        if not (math.isfinite(self.lower) and math.isfinite(self.upper)
                and -widest <= self.lower <= 0.0 <= self.upper <= widest
                and self.lower < self.upper):
            raise InputError(repr(self.text), "a range that holds the nominal (0), no wider "
                             f"than ±{_shown(widest, self.unit)}", where="bounds")

    @classmethod
    def parse(cls, text: str) -> Bound:
        """``SELECT=W`` (±W) or ``SELECT=LOW:HIGH``, with a unit: ``a2=20mm``, ``dh=-2:8deg``.

        Raises:
            InputError: naming the text and what a bound looks like (``where="bounds"``).
        """
        select, first, second, unit = _rule(text, "bounds", "a bound W or LOW:HIGH with its "
                                            "unit, e.g. dh=20mm or a2=-5:20mm")
        if second is None:
            return cls(select, unit, -abs(first), abs(first))
        return cls(select, unit, first, second)

    @property
    def text(self) -> str:
        """The rule as :meth:`parse` reads it."""
        if math.isclose(-self.lower, self.upper, rel_tol=1e-12):
            return f"{self.select}={_shown(self.upper, self.unit)}"
        return f"{self.select}={_number(self.lower, self.unit)}:" \
            f"{_shown(self.upper, self.unit)}"


@dataclass(frozen=True)
class Prior:
    """A zero-mean Gaussian prior N(0, σ²) on the unknowns ``select`` names of the unit
    ``unit``.

    Attributes:
        select: A name, family or group (module docstring).
        unit: The SI unit of the unknowns it applies to.
        sigma: σ, in ``unit``, > 0.
    """

    select: str
    unit: str
    sigma: float

    def __post_init__(self) -> None:
        widest = LARGEST.get(self.unit, 0.0)
        if not (math.isfinite(self.sigma) and 0.0 < self.sigma <= widest):
            raise InputError(repr(self.text), f"a σ > 0, at most {_shown(widest, self.unit)}",
                             where="priors")

    @classmethod
    def parse(cls, text: str) -> Prior:
        """``SELECT=σ`` with a unit: ``dh=1mm``, ``theta=0.2deg``.

        Raises:
            InputError: naming the text and what a prior looks like (``where="priors"``).
        """
        select, sigma, second, unit = _rule(text, "priors",
                                            "a prior σ with its unit, e.g. dh=1mm")
        if second is not None:
            raise InputError(repr(text), "a prior σ with its unit, e.g. dh=1mm", where="priors")
        return cls(select, unit, sigma)

    @property
    def text(self) -> str:
        """The rule as :meth:`parse` reads it."""
        return f"{self.select}={_shown(self.sigma, self.unit)}"


def parse_fix(text: str) -> str:
    """A fix rule: a name, family or group (``theta6``, ``d``, ``attachment``).

    Raises:
        InputError: for anything else (``where="fix"``).
    """
    select = text.strip()
    if not _SELECT.match(select):
        raise InputError(repr(text), "the name of an unknown, a family (a, theta…) or a group",
                         where="fix")
    return select


def _family(name: str) -> str:
    """A name without its joint number: ``a`` for a2, ``sin_q`` for sin_q3."""
    return name.rstrip("0123456789") or name


def _selected(groups: Sequence[Group], select: str, where: str) -> NDArray[np.bool_]:
    """Which unknowns of the groups (in the order of x) ``select`` names.

    Raises:
        InputError: if it names none, listing what it could name.
    """
    names = [name for group in groups for name in group.names]
    owners = [group.name for group in groups for _ in group.names]
    chosen = np.array([select in (name, _family(name), owner)
                       for name, owner in zip(names, owners, strict=True)], dtype=bool)
    if not np.any(chosen):
        families = dict.fromkeys([*(group.name for group in groups), *map(_family, names)])
        raise InputError(repr(select), "an unknown of this calibration, a family or a group: "
                         + ", ".join(families) + " (or a name such as " + names[-1] + ")"
                         if names else "unknowns to act on", where=where)
    return chosen


def _of_unit(groups: Sequence[Group], chosen: NDArray[np.bool_], rule: Bound | Prior,
             where: str) -> NDArray[np.bool_]:
    """The chosen unknowns of the rule's unit.

    Raises:
        InputError: if none has it, naming the units they have.
    """
    units = np.array([unit for group in groups for unit in group.units], dtype=object)
    matching = chosen & (units == rule.unit)
    if not np.any(matching):
        have = ", ".join(dict.fromkeys(DISPLAY_UNITS[unit][0] for unit in units[chosen]))
        raise InputError(repr(rule.text), f"a value in the unit of {rule.select} ({have})",
                         where=where)
    return matching


def restrict(groups: Sequence[Group], bounds: Sequence[Bound] = (),
             priors: Sequence[Prior] = (), fix: Sequence[str] = ()) -> tuple[Group, ...]:
    """The groups with the rules applied, in order (module docstring).

    Raises:
        InputError: for a rule that names no unknown of these groups, a value of another unit
            than the unknowns it names, or a fixed measurement unknown (``where`` the rule's
            setting: ``bounds``, ``priors``, ``fix``).
    """
    if not (bounds or priors or fix):
        return tuple(groups)
    lower = np.concatenate([group.lower for group in groups])
    upper = np.concatenate([group.upper for group in groups])
    weight = np.concatenate([group.prior_weight for group in groups])
    keep = np.ones(lower.size, dtype=bool)
    for bound in bounds:
        applies = _of_unit(groups, _selected(groups, bound.select, "bounds"), bound, "bounds")
        lower[applies], upper[applies] = bound.lower, bound.upper
    for prior in priors:
        applies = _of_unit(groups, _selected(groups, prior.select, "priors"), prior, "priors")
        weight[applies] = 1.0 / prior.sigma
    for select in fix:
        keep &= ~_selected(groups, select, "fix")
    restricted, start = [], 0
    for group in groups:
        part = slice(start, start + group.size)
        start = part.stop
        if group.stage == Stage.MEASUREMENT and not np.all(keep[part]):
            raise InputError(f"fixing {group.name}", "robot errors or the attachment: a "
                             f"measurement's unknowns ({group.name}) are fixed by not "
                             "estimating them", where="fix")
        restricted.append(group.restricted(keep[part], lower[part], upper[part], weight[part]))
    return tuple(restricted)


def group_box(group: Group, bounds: Sequence[Bound]) -> tuple[NDArray[np.float64],
                                                               NDArray[np.float64]]:
    """One group's search box under the rules that name its unknowns (the others, naming
    other groups, left aside): (lower, upper), each (p_g,). What a scenario clips its true
    errors to, so that the truth lies inside the box its calibration searches."""
    lower, upper = np.array(group.lower), np.array(group.upper)
    families = [_family(name) for name in group.names]
    units = np.array(group.units, dtype=object)
    for bound in bounds:
        chosen = np.array([bound.select in (name, family, group.name) for name, family
                           in zip(group.names, families, strict=True)], dtype=bool)
        applies = chosen & (units == bound.unit)
        lower[applies], upper[applies] = bound.lower, bound.upper
    return lower, upper


__all__ = ["LARGEST", "Bound", "Prior", "group_box", "parse_fix", "restrict"]
