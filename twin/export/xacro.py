"""The calibration as xacro properties a description includes, the description left as it is.

For each joint whose origin holds the calibration (:func:`twin.export.urdf.joint_origins`: every
moving joint of the chain and the fixed joint carrying the flange) two properties, in m and
the URDF's fixed-axis roll–pitch–yaw in rad, at full double precision::

    <xacro:property name="shoulder_pan_joint_origin_xyz" value="0.0 0.0 0.1625"/>
    <xacro:property name="shoulder_pan_joint_origin_rpy" value="0.0 0.0 0.0"/>

(a character of the joint's name that a xacro name cannot hold becomes ``_``). The description
includes the file (``<xacro:include filename="calibration.xacro"/>``, or through an argument,
as ur_description takes its kinematics file) and writes each such joint's origin as
``<origin xyz="${shoulder_pan_joint_origin_xyz}" rpy="${shoulder_pan_joint_origin_rpy}"/>``.
"""

from __future__ import annotations

import re
from xml.sax.saxutils import quoteattr

from twin.export.urdf import joint_origins
from twin.geometry.kinematics import xyz_rpy
from twin.robot import RobotModel

NAMESPACE = "http://www.ros.org/wiki/xacro"


def property_name(joint: str, part: str) -> str:
    """The property holding a joint's origin ``xyz`` or ``rpy``."""
    return re.sub(r"\W", "_", joint) + f"_origin_{part}"


def export(robot: RobotModel) -> str:
    """The properties file's text (see the module docstring)."""
    lines = ['<?xml version="1.0"?>',
             f"<!-- {robot.name}: joint origins calibrated by twin (m, rad). Include this file "
             "and write each joint's origin as xyz=\"${JOINT_origin_xyz}\" "
             "rpy=\"${JOINT_origin_rpy}\". -->",
             f'<robot xmlns:xacro="{NAMESPACE}">']
    for joint, origin in joint_origins(robot).items():
        for part, values in zip(("xyz", "rpy"), xyz_rpy(origin), strict=True):
            text = " ".join(repr(float(v) + 0.0) for v in values)
            lines.append(f"  <xacro:property name={quoteattr(property_name(joint, part))} "
                         f"value={quoteattr(text)}/>")
    lines.append("</robot>")
    return "\n".join(lines) + "\n"
