"""Reading a robot from its file: a D-H model TOML (:func:`twin.robot.parse_robot`), a URDF
(:mod:`twin.io.urdf_reader`, through Pinocchio), or a model TOML that names a URDF::

    urdf = "ur5e.urdf"               # relative to this file
    base_link = "base_link"          # optional
    tip_link = "tool0"               # optional
    parametrisation = "auto"         # optional: "dh", "mdh", "auto" or one per joint
    name = "my UR5e"                 # optional

This is the one place that knows both formats; :mod:`twin.robot` holds the model and its D-H
file alone, and :mod:`twin.io.urdf_reader` the URDF adapter.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

from twin.errors import InputError
from twin.io.paths import read_toml
from twin.io.table import Table
from twin.io.urdf_reader import load_urdf
from twin.parametrisation import AUTO
from twin.robot import RobotModel, default_robot, parametrisation_request, parse_robot

URDF_KEYS = ("name", "urdf", "base_link", "tip_link", "parametrisation")
"""The keys of a model file that names a URDF."""


def _urdf_reference(document: dict[str, Any], source: str | Path) -> RobotModel:
    """A model file that names a URDF: read the URDF with the file's links and parametrisation."""
    doc = Table(document, source, allowed=URDF_KEYS, kind="a model file that names a URDF")
    links = {key: doc.text(key) if doc.has(key) else None for key in ("base_link", "tip_link")}
    robot = load_urdf(Path(source).parent / doc.text("urdf"), base_link=links["base_link"],
                      tip_link=links["tip_link"],
                      parametrisation=parametrisation_request(doc, AUTO))
    return replace(robot, name=doc.text("name")) if doc.has("name") else robot


def load_robot(path: str | Path, *, base_link: str | None = None, tip_link: str | None = None
               ) -> RobotModel:
    """Read and validate a robot model: a TOML model file, or a URDF (``.urdf``).

    Args:
        path: The file.
        base_link: For a URDF: the link the chain starts from (default: the root).
        tip_link: For a URDF: the flange link (default: tool0, flange or the one leaf).

    Raises:
        InputError: if the file is missing, not TOML (or URDF), or not a valid model.
    """
    path = Path(path)
    if path.suffix.lower() == ".urdf":
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
                          tip_link: str | None = None) -> RobotModel:
    """The robot of a file (:func:`load_robot`), or the packaged ABB IRB 120 without one.

    Raises:
        InputError: as :func:`load_robot`.
    """
    if path is None:
        return default_robot()
    return load_robot(path, base_link=base_link, tip_link=tip_link)
