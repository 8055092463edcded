"""Unknown groups behind one interface (:class:`~twin.unknowns.base.Group`), one module each.

A calibration chooses its groups by name (``--errors``, ``errors = [...]``, the estimate flags);
this registry resolves the names. New groups plug in here and in nothing else of the core.
"""

from __future__ import annotations

from collections.abc import Callable

from twin.errors import UnknownChoiceError
from twin.rig import Rig
from twin.robot import RobotModel
from twin.unknowns import attachment, dh, offset, points, port, tracker
from twin.unknowns.base import Group, Stage

Factory = Callable[[RobotModel, Rig], Group]

GROUPS: dict[str, Factory] = {
    "dh": dh.make,
    "port": port.make,
    "offset": offset.make,
    "attachment": attachment.make,
    "base": tracker.make,
    "points": points.make,
}
"""Every unknown group, by name, in the order x lays them out."""


def make_groups(names: list[str] | tuple[str, ...], robot: RobotModel, rig: Rig
                ) -> tuple[Group, ...]:
    """The named groups for ``robot`` and ``rig``, in the registry's order.

    Raises:
        UnknownChoiceError: listing the groups.
    """
    for name in names:
        if name not in GROUPS:
            raise UnknownChoiceError("error group", name, GROUPS)
    return tuple(factory(robot, rig) for name, factory in GROUPS.items() if name in names)


__all__ = ["GROUPS", "Group", "Stage", "make_groups"]
