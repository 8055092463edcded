"""Unknown groups behind one interface (:class:`~twin.unknowns.group.Group`), one module each.

A calibration chooses its groups by name (``--errors``, ``errors = [...]``, the estimate flags);
the registry (:data:`GROUPS`, a :class:`twin.distribution.Registry` of each group's factory)
resolves the names. New groups plug in here and in nothing else of the core.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from twin.distribution import Lazy, Registry, lazy_exports
from twin.errors import InputError

if TYPE_CHECKING:
    from twin.rig import Rig
    from twin.robot import RobotModel
    from twin.unknowns.group import Group, Stage

Factory = Callable[["RobotModel", "Rig"], "Group"]

GROUPS: Registry[Factory] = Registry("error group", {
    name: Lazy(f"twin.unknowns.{module}:make") for name, module in (
        ("dh", "dh"), ("transmission", "transmission"), ("backlash", "backlash"),
        ("compliance", "compliance"), ("link_compliance", "link_compliance"),
        ("thermal", "thermal"), ("port", "port"), ("offset", "offset"), ("scale", "scale"),
        ("attachment", "attachment"), ("base", "tracker"), ("points", "points"),
        ("tool", "tool"), ("planes", "planes"))})
"""Every unknown group, by name, in the order x lays them out; a group's module is imported when
it is first made (the names alone need no numpy: the command line's help lists them)."""
ERRORS = ("dh", "transmission", "backlash", "compliance", "link_compliance", "thermal")
"""The robot's error groups, which a calibration chooses (``--errors``, ``[calibration] errors``);
the rig's (port, offset, scale) come with the estimate flags."""


def check_errors(names: Sequence[str]) -> tuple[str, ...]:
    """The robot's error groups as a set, in the registry's order: every name among
    :data:`ERRORS`, the table ``dh`` among them (every other group corrects it), and not both
    ``compliance`` and ``link_compliance``.

    Raises:
        InputError: naming what is wrong (``where="errors"``); the caller adds the flag or
            file.
    """
    names = tuple(names)
    twice = [name for name in ERRORS if names.count(name) > 1]
    if twice:
        raise InputError(f"the error group {twice[0]!r} twice", "each group once",
                         where="errors")
    unknown = [name for name in names if name not in ERRORS]
    if unknown:
        raise InputError(f"the error group {unknown[0]!r}", "groups among " + ", ".join(ERRORS),
                         where="errors")
    if "dh" not in names:
        found = f"the error groups {', '.join(names)} without dh" if names else "no error group"
        raise InputError(found,
                         "dh among them (the D-H table the joint-level groups correct)",
                         where="errors")
    if "compliance" in names and "link_compliance" in names:
        raise InputError("compliance with link_compliance", "one of them: link_compliance "
                         "holds each joint's compliance, link by link", where="errors")
    return tuple(name for name in ERRORS if name in names)


def make_groups(names: list[str] | tuple[str, ...], robot: RobotModel, rig: Rig
                ) -> tuple[Group, ...]:
    """The named groups for ``robot`` and ``rig``, in the registry's order.

    Raises:
        UnknownChoiceError: listing the groups.
        InputError: for compliance and link_compliance together (the second holds the first).
    """
    for name in names:
        GROUPS.lookup(name)
    if "compliance" in names and "link_compliance" in names:
        raise InputError("compliance with link_compliance", "one of them: link_compliance "
                         "holds each joint's compliance, link by link")
    return tuple(factory(robot, rig) for name, factory in GROUPS.items() if name in names)


__getattr__ = lazy_exports(__name__, {"twin.unknowns.group": ("Group", "Stage")})

__all__ = ["ERRORS", "GROUPS", "Group", "Stage", "check_errors", "make_groups"]
