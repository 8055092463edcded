"""URDF for ROS, MoveIt and Pinocchio, with the robot's own names.

- **A robot read from a URDF** (:mod:`twin.io.urdf_reader`): the source document written back
  with the calibrated joint origins and nothing else changed — every link, joint, mesh,
  inertial, limit, comment and name (``tool0``, ``flange``, the base link…) is kept, so
  robot_state_publisher, MoveIt configurations and drivers keep working with it.
- **A robot from a model TOML file**: a URDF with the ROS-Industrial names — ``base_link``,
  ``joint_1``…``joint_n`` (revolute about z, or prismatic along it), ``link_1``…``link_n``, and
  the flange frame as ``tool0`` on a fixed joint ``link_n-tool0`` — and the file's limits (m,
  m/s and N on a prismatic joint).

How the calibration goes in. The identified chain's fixed transforms
(:func:`twin.geometry.kinematics.fixed_transforms`) give every joint's frame at q = 0, the joint
turning about (or sliding along) its z axis. When the robot was read, each URDF joint's frame
(turned so that its axis is z) was recorded as a shift along and a turn about that same axis from
the table's frame (:attr:`twin.robot.UrdfSource.frame_offsets`); such a screw commutes with the
joint's turn or slide, so the calibrated URDF joint frame is the calibrated table frame with the
same screw, and each link frame — with its meshes and inertials — moves by the calibration alone.
Moving joint k's origin is then its calibrated frame seen from its parent link, through the fixed
joints between them (unchanged), its ``<axis>`` unchanged. The flange's calibrated place goes
into the first fixed joint between the last moving joint and the tip link; when the tip link is
the last joint's own child, only a turn about and a shift along the last axis can go into that
joint's origin, and a calibration that moves the flange off its axis is refused (name a tip link
after a fixed joint, such as ``tool0``).

Origins are written as ``xyz`` (m) and fixed-axis ``rpy`` (rad) at full double precision, so that
Pinocchio's forward kinematics of the file equals the identified model's to 1e-9 m
(``tests/test_export_ros.py``).
"""

from __future__ import annotations

import sys
import xml.etree.ElementTree as ET
from xml.sax.saxutils import quoteattr

import numpy as np

from twin.arrays import Array
from twin.geometry.kinematics import fixed_transforms, xyz_rpy
from twin.geometry.parametrisation import joint_frames
from twin.io.urdf_reader import MOVING, axis_alignment, find_chain, joint_axis, origin_transform
from twin.robot import RobotModel

SCREW_TOLERANCE = 1e-12
"""How far (m, rad) the flange may move other than about and along the last axis when the
tip link is the last joint's child (its origin can hold nothing else)."""
NO_LIMIT = sys.float_info.max
"""Written for a rated speed or torque the model file does not give: the largest double, what
Pinocchio itself takes for "no limit" (0 would stop a simulated joint; URDF needs a number)."""
TOOL_LINK = "tool0"
SOURCE = "the robot's URDF"


def _number(value: float) -> str:
    return repr(float(value) + 0.0)


def _origin_attributes(transform: Array) -> dict[str, str]:
    xyz, rpy = xyz_rpy(transform)
    return {"xyz": " ".join(map(_number, xyz)), "rpy": " ".join(map(_number, rpy))}


def _axis(joint: ET.Element) -> Array:
    """The joint's axis alignment R (z to its axis) as a 4×4 transform."""
    transform = np.eye(4)
    transform[:3, :3] = axis_alignment(joint_axis(joint, SOURCE))
    return transform


def _product(joints: list[ET.Element]) -> Array:
    transform = np.eye(4)
    for joint in joints:
        transform = transform @ origin_transform(joint, SOURCE)
    return transform


def _screw(shift_m: float, turn_rad: float) -> Array:
    """Tz(shift) · Rz(turn)."""
    c, s = np.cos(turn_rad), np.sin(turn_rad)
    return np.array([[c, -s, 0.0, 0.0], [s, c, 0.0, 0.0], [0.0, 0.0, 1.0, shift_m],
                     [0.0, 0.0, 0.0, 1.0]])


def _calibrated_origins(robot: RobotModel, root: ET.Element) -> dict[str, Array]:
    """The joint origins of a URDF robot's chain that calibration changes, by joint name."""
    source = robot.urdf
    assert source is not None
    chain = find_chain(root, source.base_link, source.tip_link, SOURCE)
    groups: list[list[ET.Element]] = [[]]  # fixed joints before each moving one, then the tail
    revolute: list[ET.Element] = []
    for joint in chain.joints:
        if joint.get("type") in MOVING:
            revolute.append(joint)
            groups.append([])
        else:
            groups[-1].append(joint)
    fixed = fixed_transforms(robot.structure, robot.dh)
    joints, flange = joint_frames(fixed)
    # The URDF's joint frames, calibrated: the table's, with the nominal offsets along and
    # about each axis (which commute with the joint's turn, so the chain is unchanged).
    calibrated = [frame @ _screw(*offset) for frame, offset in
                  zip(joints, source.frame_offsets, strict=True)]
    origins: dict[str, Array] = {}
    link = np.eye(4)  # the previous revolute joint's child link (the base link at first)
    alignment = np.eye(4)
    for k, joint in enumerate(revolute):
        alignment = _axis(joint)
        origins[str(joint.get("name"))] = (np.linalg.inv(link @ _product(groups[k]))
                                           @ calibrated[k] @ alignment.T)
        link = calibrated[k] @ alignment.T
    tail = groups[-1]
    if tail:
        rest = _product(tail[1:])
        origins[str(tail[0].get("name"))] = np.linalg.inv(link) @ flange @ np.linalg.inv(rest)
        return origins
    # The tip is the last joint's child: only a screw about its axis fits in its origin.
    screw = np.linalg.inv(calibrated[-1]) @ flange @ alignment  # nominally the identity
    off_axis = max(float(np.abs(screw[:2, 3]).max()), float(np.abs(screw[:2, 2]).max()))
    if off_axis > SCREW_TOLERANCE:
        raise ValueError(f"the flange moved {off_axis:.3g} m off the last joint's axis, which "
                         f"the URDF cannot hold: its tip link {chain.tip_link!r} is the last "
                         "joint's own child (load the robot with a tip link after a fixed "
                         "joint, e.g. tool0)")
    name = str(revolute[-1].get("name"))
    origins[name] = origins[name] @ alignment @ screw @ alignment.T
    return origins


def joint_origins(robot: RobotModel) -> dict[str, Array]:
    """The origin of every joint whose origin holds the robot's calibration, by joint name:
    each moving joint of the chain and the fixed joint that carries the flange, (4, 4) in the
    parent link's frame, m.

    Raises:
        ValueError: for a URDF whose tip link cannot hold the calibrated flange (see the
            module docstring).
    """
    if robot.urdf is not None:
        return _calibrated_origins(robot, ET.fromstring(robot.urdf.text))
    fixed = fixed_transforms(robot.structure, robot.dh)
    names = [*robot.joint_names, f"link_{robot.n_joints}-{TOOL_LINK}"]
    return dict(zip(names, fixed, strict=True))


def _write_back(robot: RobotModel) -> str:
    assert robot.urdf is not None
    text = robot.urdf.text
    root = ET.fromstring(text, ET.XMLParser(target=ET.TreeBuilder(insert_comments=True)))
    origins = joint_origins(robot)
    for joint in root.iter("joint"):
        name = str(joint.get("name"))
        if name not in origins:
            continue
        origin = joint.find("origin")
        if origin is None:
            origin = ET.Element("origin")
            joint.insert(0, origin)
            origin.tail = "\n    "
        origin.attrib.update(_origin_attributes(origins[name]))
    declaration = '<?xml version="1.0"?>\n' if text.lstrip().startswith("<?xml") else ""
    return declaration + ET.tostring(root, encoding="unicode") + "\n"


def _limit(value: float | None) -> str:
    return _number(NO_LIMIT if value is None else value)


def _conventional(robot: RobotModel) -> str:
    origins = joint_origins(robot)
    n = robot.n_joints
    velocity = [None] * n if robot.velocity_rad_s is None else list(robot.velocity_rad_s)
    effort = [None] * n if robot.effort_nm is None else list(robot.effort_nm)
    lines = ['<?xml version="1.0"?>',
             f"<!-- {robot.name}: written by twin export from a model file "
             f"({'/'.join(sorted(set(robot.structure.parametrisation)))} table). Joint i turns "
             "about (prismatic: slides along) z of its frame; tool0 is the flange frame. -->"]
    missing = [what for what, values in (("speed", robot.velocity_rad_s),
                                         ("torque", robot.effort_nm)) if values is None]
    if missing:
        lines.append(f"<!-- The model file gives no rated {' or '.join(missing)}: "
                     f"{_number(NO_LIMIT)} stands for no known limit, as in Pinocchio. -->")
    lines += [f"<robot name={quoteattr(robot.name)}>", '  <link name="base_link"/>']
    parent = "base_link"
    for i, (name, origin) in enumerate(list(origins.items())[:n]):
        child = f"link_{i + 1}"
        attributes = _origin_attributes(origin)
        lines += [
            f'  <link name="{child}"/>',
            f'  <joint name="{name}" type="{robot.structure.joint_types[i]}">',
            f'    <parent link="{parent}"/>',
            f'    <child link="{child}"/>',
            f'    <origin xyz="{attributes["xyz"]}" rpy="{attributes["rpy"]}"/>',
            '    <axis xyz="0 0 1"/>',
            f'    <limit lower="{_number(robot.lower_rad[i])}" '
            f'upper="{_number(robot.upper_rad[i])}" effort="{_limit(effort[i])}" '
            f'velocity="{_limit(velocity[i])}"/>',
            "  </joint>",
        ]
        parent = child
    tool_joint, tool = list(origins.items())[n]
    attributes = _origin_attributes(tool)
    lines += [
        f'  <link name="{TOOL_LINK}"/>',
        f'  <joint name="{tool_joint}" type="fixed">',
        f'    <parent link="{parent}"/>',
        f'    <child link="{TOOL_LINK}"/>',
        f'    <origin xyz="{attributes["xyz"]}" rpy="{attributes["rpy"]}"/>',
        "  </joint>",
        "</robot>",
    ]
    return "\n".join(lines) + "\n"


def export(robot: RobotModel) -> str:
    """URDF text of the robot: its own URDF with the calibrated origins when it was read from
    one, else a URDF with ROS-Industrial names (see the module docstring).

    Raises:
        ValueError: for a URDF whose tip link cannot hold the calibrated flange.
    """
    return _write_back(robot) if robot.urdf is not None else _conventional(robot)
