"""MJCF for MuJoCo, from the twin's own model builder: hinge joints and a site ``flange``.

The joint positions ``qpos`` are the D-H joint angles q (the θ offsets sit in the bodies'
orientations), so the flange site's pose equals :func:`twin.kinematics.flange_transform`.

MuJoCo's XML writer keeps 6 significant digits, which moves the flange by up to a micrometre;
the kinematic attributes (body and flange ``pos`` / ``quat``, joint ``range``) are written again
from the spec at full double precision, so the exported FK agrees to 1e-9 m.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np

from twin.robot import RobotModel
from twin.sim.builder import build_spec, model_xml


def _exact(values: object) -> str:
    return " ".join(repr(float(v)) for v in np.ravel(np.asarray(values, dtype=np.float64)))


def export(robot: RobotModel) -> str:
    """MJCF text of the arm alone (no port, no cable), rigid."""
    spec = build_spec(robot)
    root = ET.fromstring(model_xml(robot), ET.XMLParser(target=ET.TreeBuilder(
        insert_comments=True)))
    for body in root.iter("body"):
        source = spec.body(body.attrib["name"])
        body.set("pos", _exact(source.pos))
        body.set("quat", _exact(source.quat))
    for joint in root.iter("joint"):
        joint.set("range", _exact(spec.joint(joint.attrib["name"]).range))
    for site in root.iter("site"):
        source = spec.site(site.attrib["name"])
        site.set("pos", _exact(source.pos))
        site.set("quat", _exact(source.quat))
    ET.indent(root)
    return ET.tostring(root, encoding="unicode") + "\n"
