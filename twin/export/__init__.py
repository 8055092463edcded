"""Export a robot model (typically the identified one) to the formats other tools read.

Each format is a module here named after its ``--format`` value, with ``export(robot) -> str``,
registered in :data:`FORMATS`
(so ``export/urdf.py`` writes URDFs, :mod:`twin.io.urdf_reader` reads them); a format's heavy
dependency (MuJoCo) is imported only when that format is asked for.

- ``dh``: the `models/` TOML format (:func:`twin.io.robot_file.robot_to_toml`), mm and degrees, in
the
  robot's parametrisation;
- ``urdf``: URDF for ROS / MoveIt / Pinocchio: the robot's own URDF with the calibrated joint
  origins, or ROS-Industrial names (``base_link``, ``joint_i``, ``link_i``, ``tool0``) for a
  robot from a model file;
- ``yaml``: the calibrated joint origins as an overlay in the style of Universal Robots'
  calibration files;
- ``mjcf``: MJCF for MuJoCo, with a site ``flange`` (the twin's own builder);
- ``ur-calibration``: a UR robot's calibration in the layout of Universal Robots'
  ``ur_calibration`` (``kinematics: shoulder … wrist_3, hash``), which ``ur_description`` reads;
- ``xacro``: the calibrated joint origins as xacro properties a description includes.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from twin.distribution import Lazy, Registry

if TYPE_CHECKING:
    from twin.robot import RobotModel

Exporter = Callable[["RobotModel"], str]

FORMATS: Registry[Exporter] = Registry("export format", {
    name: Lazy(f"twin.export.{name.replace('-', '_')}:export")
    for name in ("dh", "urdf", "yaml", "mjcf", "ur-calibration", "xacro")})
"""Every format's ``export`` function, by ``--format`` name; each module is imported when its
format is asked for."""


def export_text(robot: RobotModel, format_name: str) -> str:
    """The robot as the text of a file in ``format_name``.

    Raises:
        UnknownChoiceError: if the format is not one of :data:`FORMATS`.
    """
    return str(FORMATS.lookup(format_name, source="--format")(robot))
