"""MJCF for MuJoCo, from the twin's own model builder: hinge joints (slides for prismatic
ones, q in m) and a site ``flange``.

The joint positions ``qpos`` are the D-H joint values q (the θ and d offsets sit in the bodies'
placements), so the flange site's pose equals :func:`twin.geometry.kinematics.flange_transform`;
:func:`twin.sim.builder.model_xml` writes the kinematic attributes at full double precision,
so the exported FK agrees to 1e-9 m.
"""

from __future__ import annotations

from twin.robot import RobotModel
from twin.sim.builder import model_xml


def export(robot: RobotModel) -> str:
    """MJCF text of the arm alone (no port, no cable), rigid."""
    return model_xml(robot)
