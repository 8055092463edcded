"""The calibration as a joint-origin overlay in the style of Universal Robots' calibration files
(``ur_description``'s ``default_kinematics.yaml``, what ``ur_calibration`` writes), for a URDF
built from a xacro that takes its joint origins from such a file::

    kinematics:
      shoulder_pan_joint:
        x: 0.0
        y: 0.0
        z: 0.1625
        roll: 0.0
        pitch: 0.0
        yaw: 0.0
      ...

One entry per joint whose origin holds the calibration (every moving joint of the chain and
the fixed joint carrying the flange, :func:`twin.export.urdf.joint_origins`), keyed by the
URDF's joint names (``joint_1``… for a robot from a model file): ``x, y, z`` in m and fixed-axis
``roll, pitch, yaw`` in rad, in the parent link's frame, at full double precision. UR's own
files key the entries by link (``shoulder``, ``upper_arm``…): map them to these joints when
feeding a UR xacro.
"""

from __future__ import annotations

from twin.export.urdf import joint_origins
from twin.geometry.kinematics import xyz_rpy
from twin.robot import RobotModel


def export(robot: RobotModel) -> str:
    """YAML text of the robot's joint origins (see the module docstring)."""
    source = robot.urdf
    links = f"{source.base_link} to {source.tip_link}" if source is not None \
        else f"base_link to tool0 (link_{robot.n_joints})"
    lines = [f"# {robot.name}: joint origins, chain {links}; x, y, z in m, roll, pitch, yaw in",
             "# rad (fixed axes), each in its parent link's frame. Written by twin export.",
             "kinematics:"]
    for name, origin in joint_origins(robot).items():
        xyz, rpy = xyz_rpy(origin)
        lines.append(f"  {name}:")
        lines += [f"    {key}: {float(value) + 0.0!r}"
                  for key, value in zip(("x", "y", "z", "roll", "pitch", "yaw"),
                                        (*xyz, *rpy), strict=True)]
    return "\n".join(lines) + "\n"
