"""A UR robot's calibration in the layout of Universal Robots' ``ur_calibration`` package: the file
``ur_description`` reads as ``kinematics_parameters_file`` (``default_kinematics.yaml``, the
output of ``ur_calibration``'s ``calibration_correction``)::

    kinematics:
      shoulder:  {x: …, y: …, z: …, roll: …, pitch: …, yaw: …}
      upper_arm: …
      forearm: …
      wrist_1: …
      wrist_2: …
      wrist_3: …
      hash: calib_12788084448423163542

Each entry is the ``<origin>`` of one revolute joint in ``ur_description``'s ``ur_macro.xacro``
(shoulder → ``shoulder_pan_joint``, upper_arm → ``shoulder_lift_joint``, forearm →
``elbow_joint``, wrist_1..3 → ``wrist_1..3_joint``): ``x, y, z`` in m and the URDF's fixed-axis
``roll, pitch, yaw`` in rad, in the parent link's frame (source: Universal_Robots_ROS2_Description
commit 2221ec0, ``urdf/inc/ur_common.xacro``; BSD-3-Clause; layout facts only, no code). The
fixed joints after ``wrist_3_link`` (``flange``, ``tool0``) are constants of the macro: the
calibrated flange must be a turn about and a shift along the last axis from them, which folds
into ``wrist_3`` exactly; what moves it off that axis (the last row's a and α: a cable sees a)
has no place in the file (``ur_calibration`` itself drops the last row's a and α). It is a fixed
transform after the last joint, so a TCP holds it: the export warns with that offset in tool0
(mm, and a rotation vector in rad, PolyScope's TCP convention), :func:`tcp_remainder`; the file
and that TCP offset together are the identified robot.

The ``hash`` is what the driver compares with the one the robot reports for its own factory
calibration (``kinematics/hash``; Universal_Robots_ROS_Driver ``hardware_interface.cpp``): on a
mismatch it logs an error and runs as usual. Given the file the user extracted from the robot
(``--base``), its hash, comments and key order are kept (ruamel.yaml round trip) and only the
numbers change, so the driver still recognises the robot; without one, the hash is
``twin_<digest of the numbers>``, which matches no robot, and the driver says so.
"""

from __future__ import annotations

import hashlib
import io
import warnings
import xml.etree.ElementTree as ET
from typing import Any, NamedTuple

import numpy as np

from twin.arrays import Array
from twin.errors import InputError
from twin.export.urdf import joint_origins
from twin.geometry.kinematics import rigid_transform, xyz_rpy
from twin.geometry.rigid import log_rotation
from twin.io.urdf_reader import find_chain
from twin.report.display import AS_GIVEN, mm_values, plain
from twin.robot import RobotModel

UR_LINKS = {"shoulder_pan_joint": "shoulder", "shoulder_lift_joint": "upper_arm",
            "elbow_joint": "forearm", "wrist_1_joint": "wrist_1", "wrist_2_joint": "wrist_2",
            "wrist_3_joint": "wrist_3"}
"""ur_description's revolute joints (after any tf_prefix) and the kinematics entry of each."""
KEYS = ("x", "y", "z", "roll", "pitch", "yaw")
NEGLIGIBLE_M = 1e-12
"""A remainder below this (m, or rad) is rounding, not a calibration: nothing to warn about."""
NOMINAL_TOLERANCE = 1e-6
"""How far (m, rad) a --base file's numbers may be from the nominal robot's before a warning."""


class UrCalibrationWarning(UserWarning):
    """A UR calibration file that holds the result only approximately, or a base file that is
    not the nominal robot's."""


def _ur_names(robot: RobotModel) -> dict[str, str]:
    """UR entry name by URDF joint name, or an InputError for another robot."""
    names = robot.joint_names
    found = {}
    for joint in names:
        suffix = next((ur for ur in UR_LINKS if joint.endswith(ur)), None)
        if suffix is not None:
            found[joint] = UR_LINKS[suffix]
    if robot.urdf is None or len(found) != 6 or len(set(found.values())) != 6:
        raise InputError(f"a robot with joints {', '.join(names)}", "a UR robot read from its "
                         "URDF or xacro (joints shoulder_pan_joint … wrist_3_joint)",
                         source="--format")
    return found


def _origin(joint: ET.Element) -> Array:
    origin = joint.find("origin")
    if origin is None:
        return np.eye(4)
    return rigid_transform([float(v) for v in origin.get("xyz", "0 0 0").split()],
                           [float(v) for v in origin.get("rpy", "0 0 0").split()])


class UrOrigins(NamedTuple):
    """What UR's file holds of a calibrated chain, and what it cannot."""

    origins: dict[str, Array]
    """The six joint origins (4, 4), m, by entry name."""
    tcp_remainder: Array
    """tool0 as calibrated, in tool0 as the file gives it (4, 4): the TCP offset that makes
    the file the identified robot (the identity when the flange stays on the last axis)."""


def _fixed_product(joints: list[ET.Element]) -> Array:
    transform = np.eye(4)
    for joint in joints:
        transform = transform @ _origin(joint)
    return transform


def ur_origins(robot: RobotModel) -> UrOrigins:
    """The six joint origins of UR's file for the robot's calibrated chain with the macro's
    fixed flange, and the TCP offset it cannot hold (see the module docstring).

    Raises:
        InputError: for a robot that is not a UR read from its URDF (or xacro).
    """
    names = _ur_names(robot)
    assert robot.urdf is not None
    origins = joint_origins(robot)
    root = ET.fromstring(robot.urdf.text)
    chain = find_chain(root, robot.urdf.base_link, robot.urdf.tip_link, "the robot's URDF")
    last = chain.moving[-1]
    axis = last.find("axis")
    if axis is None or not np.allclose([float(v) for v in axis.get("xyz", "1 0 0").split()],
                                       [0.0, 0.0, 1.0], rtol=0.0, atol=1e-12):
        raise InputError(f"joint {last.get('name')} turning about another axis than z",
                         "a UR description (every joint about z)", source="--format")
    result = {names[joint]: origins[joint] for joint in robot.joint_names}
    tail = list(chain.joints[chain.joints.index(last) + 1:])
    if not tail:
        return UrOrigins(result, np.eye(4))
    # The flange's change, seen from wrist_3_link: its screw about z folds into wrist_3.
    nominal = _origin(tail[0])
    change = origins[str(tail[0].get("name"))] @ np.linalg.inv(nominal)
    screw = rigid_transform([0.0, 0.0, change[2, 3]],
                            [0.0, 0.0, np.arctan2(change[1, 0], change[0, 0])])
    result["wrist_3"] = result["wrist_3"] @ screw
    to_tool0 = nominal @ _fixed_product(tail[1:])
    remainder = np.linalg.inv(to_tool0) @ np.linalg.inv(screw) @ change @ to_tool0
    return UrOrigins(result, remainder)


def _warn_remainder(remainder: Array) -> None:
    shift = remainder[:3, 3]
    turn = log_rotation(remainder[:3, :3])
    if max(float(np.abs(shift).max()), float(np.abs(turn).max())) <= NEGLIGIBLE_M:
        return
    warnings.warn("the calibration moves tool0 off the last axis, which UR's file cannot hold "
                  "(its flange is fixed to wrist_3_link): add it to the TCP, in tool0: "
                  f"x,y,z = {mm_values(shift, significant=AS_GIVEN)} mm, rotation vector "
                  f"{', '.join(plain(v, significant=AS_GIVEN) for v in turn)} rad (or export "
                  "--format urdf, which "
                  "holds it)", UrCalibrationWarning, stacklevel=3)


def _values(transform: Array) -> list[float]:
    xyz, rpy = xyz_rpy(transform)
    return [float(v) + 0.0 for v in (*xyz, *rpy)]


def export(robot: RobotModel) -> str:
    """The file's text, with a ``twin_…`` hash (no robot's)."""
    found = ur_origins(robot)
    _warn_remainder(found.tcp_remainder)
    values = {name: _values(origin) for name, origin in found.origins.items()}
    digest = hashlib.sha256(repr(sorted(values.items())).encode()).hexdigest()[:16]
    lines = [f"# {robot.name}: joint origins calibrated by twin (x, y, z in m; roll, pitch, yaw "
             "in rad),", "# for ur_description's kinematics_parameters_file. The hash is no "
             "robot's: give --base", "# with the file ur_calibration extracted to keep that "
             "robot's.", "kinematics:"]
    for name, numbers in values.items():
        lines.append(f"  {name}:")
        lines += [f"    {key}: {value!r}" for key, value in zip(KEYS, numbers, strict=True)]
    lines.append(f"  hash: twin_{digest}")
    return "\n".join(lines) + "\n"


def _check_base(document: Any, source: str) -> Any:
    kinematics = document.get("kinematics") if hasattr(document, "get") else None
    if kinematics is None or not hasattr(kinematics, "get") or "hash" not in kinematics:
        raise InputError("no kinematics with a hash", "a ur_calibration file (kinematics: "
                         "shoulder … wrist_3, hash)", source=source)
    for name in UR_LINKS.values():
        entry = kinematics.get(name)
        if not hasattr(entry, "get") or any(
                not isinstance(entry.get(key), int | float) or isinstance(entry.get(key), bool)
                for key in KEYS):
            raise InputError(f"kinematics.{name} without numbers {', '.join(KEYS)}",
                             "a ur_calibration file", source=source, where=f"kinematics.{name}")
    return kinematics


def export_with_base(robot: RobotModel, base_text: str, source: str) -> str:
    """The file given (``--base``) with the robot's calibrated numbers, its hash, comments and
    order kept; a warning when its numbers were not the nominal robot's (the result replaces
    them with the ones identified from that nominal).

    Raises:
        InputError: for a base that is not YAML or not a ur_calibration file.
    """
    from ruamel.yaml import YAML
    from ruamel.yaml.error import YAMLError

    yaml = YAML()
    yaml.preserve_quotes = True
    try:
        document = yaml.load(base_text)
    except YAMLError as exc:
        raise InputError(f"YAML that does not parse ({str(exc).splitlines()[0]})",
                         "a ur_calibration file", source=source) from None
    kinematics = _check_base(document, source)
    assert robot.urdf is not None
    root = ET.fromstring(robot.urdf.text)
    nominal = {UR_LINKS[suffix]: _origin(joint) for joint in root.iter("joint")
               for suffix in UR_LINKS if str(joint.get("name")).endswith(suffix)}
    apart = max(float(np.abs(rigid_transform([kinematics[name][k] for k in KEYS[:3]],
                                             [kinematics[name][k] for k in KEYS[3:]])
                             - origin).max()) for name, origin in nominal.items())
    if apart > NOMINAL_TOLERANCE:
        warnings.warn(f"{source}: its kinematics are {apart:.3g} (m or rad) from the nominal "
                      f"robot's the result was identified for ({robot.name}): replaced by the "
                      "identified ones", UrCalibrationWarning, stacklevel=2)
    found = ur_origins(robot)
    _warn_remainder(found.tcp_remainder)
    for name, origin in found.origins.items():
        for key, value in zip(KEYS, _values(origin), strict=True):
            kinematics[name][key] = value
    stream = io.StringIO()
    yaml.dump(document, stream)
    return stream.getvalue()
