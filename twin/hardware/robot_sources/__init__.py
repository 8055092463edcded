"""Robot sources behind one interface
(:class:`~twin.hardware.robot_sources.base.RobotSource`): where the joint angles of each
captured pose come from. Each lives in its own module and exports ``KIND``
(:class:`~twin.hardware.robot_sources.base.SourceKind`); this registry resolves a
``--robot-source`` value to it.

- ``sim`` (:mod:`twin.hardware.robot_sources.sim`): the twin's robot, publishing its pose to
  the virtual encoder;
- ``manual`` (:mod:`twin.hardware.robot_sources.manual`): the operator jogs the robot and
  confirms;
- ``file`` (:mod:`twin.hardware.robot_sources.file`): joint angles logged by the robot
  controller;
- ``rws://HOST[:PORT]``, ``rws2://HOST[:PORT]`` (:mod:`twin.hardware.robot_sources.rws`): an
  ABB controller over Robot Web Services 1.0 (IRC5) or 2.0 (OmniCore).
"""

from __future__ import annotations

from twin.distribution import Registry
from twin.errors import UnknownChoiceError
from twin.hardware.robot_sources import file, manual, rws, sim
from twin.hardware.robot_sources.base import (
    Cell,
    RobotSource,
    SourceKind,
    SourceRequest,
)

SOURCES: Registry[SourceKind] = Registry("robot source", {kind.name: kind for kind in (
    sim.KIND, manual.KIND, file.KIND, rws.KIND, rws.KIND2)})
"""Every robot source, by its ``--robot-source`` name or URL scheme (the one plug-in mechanism
of :mod:`twin.distribution`)."""


def source_choices() -> list[str]:
    """How each source is written on the command line, for help texts and messages."""
    return [f"{name}://HOST[:PORT]" if name.startswith("rws") else name for name in SOURCES]


def get_source(spec: str) -> SourceKind:
    """The source a ``--robot-source`` value names: a name, or a URL whose scheme is one.

    Raises:
        UnknownChoiceError: listing the valid sources.
    """
    name = spec.split("://", 1)[0] if "://" in spec else spec
    if name not in SOURCES or (name.startswith("rws") != ("://" in spec)):
        raise UnknownChoiceError("robot source", spec, source_choices(),
                                 source="--robot-source")
    return SOURCES[name]


def open_source(request: SourceRequest) -> RobotSource:
    """Open the source ``request.spec`` names.

    Raises:
        InputError: for an unknown source or a setting it refuses.
    """
    return get_source(request.spec).open(request)


__all__ = ["SOURCES", "Cell", "RobotSource", "SourceKind", "SourceRequest", "get_source",
           "open_source", "source_choices"]
