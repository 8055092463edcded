"""ROS-ready results: a calibration written back into the robot's own URDF, names kept, and as
a UR-style joint-origin overlay; Pinocchio's forward kinematics of the export is the identified
model's."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from twin.calibration.pipeline import calibrate
from twin.cli import main
from twin.errors import InputError
from twin.export import export_text
from twin.export.pinocchio import urdf_flange
from twin.export.urdf import NO_LIMIT
from twin.geometry.kinematics import rigid_transform
from twin.io.identified import load_result_delta
from twin.io.results import result_to_dict, write_json
from twin.io.robot_file import default_robot, load_robot
from twin.io.urdf_reader import load_urdf
from twin.robot import RobotModel, random_poses
from twin.synthetic import synthesize

MODELS = Path(__file__).resolve().parents[1] / "models"
URDFS = {"ur5e": MODELS / "ur5e" / "ur5e.urdf", "fr3": MODELS / "fr3" / "fr3.urdf",
         "irb120": MODELS / "irb120" / "irb120_3_58.urdf"}
PORT_M = np.array([0.6, -0.4, 0.1])


def _perturbed(robot: RobotModel, seed: int) -> RobotModel:
    rng = np.random.default_rng(seed)
    scale = np.where(robot.is_length, 2e-3, np.deg2rad(0.5))
    return robot.perturbed(rng.uniform(-1.0, 1.0, scale.shape) * scale)


def _elements(text: str) -> dict[str, dict[str, str]]:
    """Every element of a URDF but the joint origins, keyed by path, with its attributes."""
    root = ET.fromstring(text)
    found: dict[str, dict[str, str]] = {}
    for kind in ("link", "joint"):
        for element in root.findall(kind):
            for index, child in enumerate(element.iter()):
                if kind == "joint" and child.tag == "origin":
                    continue
                found[f"{kind}:{element.get('name')}/{index}:{child.tag}"] = dict(child.attrib)
    return found


@pytest.mark.parametrize("request_", ["auto", "dh"])
@pytest.mark.parametrize("name", list(URDFS))
def test_urdf_written_back_is_the_identified_robot(name: str, request_: str) -> None:
    """An identified robot read from a URDF, exported to URDF: Pinocchio's pose of the tip link
    equals the identified flange to 1e-9 m over 1000 poses, and every link, joint, name, mesh,
    inertial and limit is the source's — only joint origins differ."""
    nominal = load_urdf(URDFS[name], parametrisation=request_)
    identified = _perturbed(nominal, 1)
    text = export_text(identified, "urdf")
    assert identified.urdf is not None
    q = random_poses(identified, 1000, np.random.default_rng(2))
    found = urdf_flange(text, identified.joint_names, q, identified.urdf.tip_link,
                        identified.urdf.base_link)
    np.testing.assert_allclose(found, identified.flange_transforms(q), rtol=0.0, atol=1e-9)
    assert _elements(text) == _elements(identified.urdf.text)
    model = pin.buildModelFromXML(text)
    source = pin.buildModelFromXML(identified.urdf.text)
    assert list(model.names) == list(source.names)
    assert [f.name for f in model.frames] == [f.name for f in source.frames]


def test_nominal_export_keeps_the_origins_and_links_move_by_the_calibration_only() -> None:
    """The nominal UR5e written back has the source's joint origins (to 1e-12); a calibration
    moves every link frame by about its own size (mm, mrad), never by a nominal offset (the
    shoulder stays 162.5 mm up, the meshes with it)."""
    nominal = load_robot(URDFS["ur5e"])
    assert nominal.urdf is not None
    exported = ET.fromstring(export_text(nominal, "urdf"))
    source = ET.fromstring(nominal.urdf.text)

    def origins(root: ET.Element) -> dict[str, np.ndarray]:
        result = {}
        for joint in root.findall("joint"):
            origin = joint.find("origin")
            assert origin is not None
            result[str(joint.get("name"))] = rigid_transform(
                [float(v) for v in origin.get("xyz", "0 0 0").split()],
                [float(v) for v in origin.get("rpy", "0 0 0").split()])
        return result

    before, after = origins(source), origins(exported)
    assert before.keys() == after.keys()
    for joint in before:
        np.testing.assert_allclose(after[joint], before[joint], rtol=0.0, atol=1e-12)
    calibrated = origins(ET.fromstring(export_text(_perturbed(nominal, 3), "urdf")))
    shift = max(float(np.abs(calibrated[j][:3, 3] - before[j][:3, 3]).max()) for j in before)
    assert 1e-5 < shift < 1e-2
    assert calibrated["shoulder_pan_joint"][2, 3] == pytest.approx(0.1625, abs=1e-12)


def test_tip_on_the_last_joint_takes_only_a_screw(tmp_path: Path) -> None:
    """With the tip link the last joint's own child, a calibration that only turns about and
    shifts along the last axis is written into that joint's origin; one that moves the flange
    off the axis is refused (the URDF cannot hold it)."""
    robot = load_robot(URDFS["ur5e"], tip_link="wrist_3_link")
    screw = robot.perturbed(np.where(np.arange(24) == 23, 1e-3, 0.0)
                            + np.where(np.arange(24) == 11, 1e-3, 0.0))  # θ6, d6
    assert screw.urdf is not None
    q = random_poses(screw, 200, np.random.default_rng(4))
    found = urdf_flange(export_text(screw, "urdf"), screw.joint_names, q, "wrist_3_link",
                        screw.urdf.base_link)
    np.testing.assert_allclose(found, screw.flange_transforms(q), rtol=0.0, atol=1e-9)
    with pytest.raises(ValueError, match="off the last joint's axis"):
        export_text(robot.perturbed(np.where(np.arange(24) == 5, 1e-3, 0.0)), "urdf")  # a6


@pytest.mark.parametrize("maker", ["irb120", "scara4"])
def test_model_file_urdf_has_ros_industrial_names_and_real_limits(maker: str) -> None:
    """From a model file: base_link, joint_1..n, link_1..n and tool0 on link_n-tool0; the
    file's limits, rated speeds where it gives them and no zero; FK equal to 1e-9 m."""
    robot = default_robot() if maker == "irb120" else load_robot(MODELS / "scara4" /
                                                                "scara4.toml")
    identified = _perturbed(robot, 5)
    text = export_text(identified, "urdf")
    root = ET.fromstring(text)
    n = robot.n_joints
    assert [link.get("name") for link in root.findall("link")] == \
        ["base_link", *(f"link_{i}" for i in range(1, n + 1)), "tool0"]
    assert [joint.get("name") for joint in root.findall("joint")] == \
        [*(f"joint_{i}" for i in range(1, n + 1)), f"link_{n}-tool0"]
    limits = [joint.find("limit") for joint in root.findall("joint")][:n]
    velocity = [float(str(limit.get("velocity"))) for limit in limits if limit is not None]
    effort = [float(str(limit.get("effort"))) for limit in limits if limit is not None]
    expected = robot.velocity_rad_s if robot.velocity_rad_s is not None else [NO_LIMIT] * n
    np.testing.assert_allclose(velocity, expected)
    assert effort == [NO_LIMIT] * n and min(velocity) > 0
    q = random_poses(identified, 1000, np.random.default_rng(6))
    found = urdf_flange(text, [f"joint_{i}" for i in range(1, n + 1)], q, "tool0")
    np.testing.assert_allclose(found, identified.flange_transforms(q), rtol=0.0, atol=1e-9)


def _overlay(text: str) -> dict[str, dict[str, float]]:
    """The kinematics: block of a YAML overlay (the writer's own simple layout)."""
    entries: dict[str, dict[str, float]] = {}
    joint = ""
    for line in text.splitlines():
        if line.startswith("#") or line == "kinematics:":
            continue
        key, value = line.strip().split(":", 1)
        if line.startswith("    "):
            entries[joint][key] = float(value)
        else:
            joint = key
            entries[joint] = {}
    return entries


def test_yaml_overlay_is_the_urdfs_origins() -> None:
    """The YAML overlay has one entry per revolute joint and the flange's fixed joint, keyed by
    the URDF's joint names; putting its x, y, z, roll, pitch, yaw into the source URDF gives
    the identified robot (Pinocchio, 1e-9 m)."""
    identified = _perturbed(load_robot(URDFS["ur5e"]), 7)
    assert identified.urdf is not None
    overlay = _overlay(export_text(identified, "yaml"))
    assert list(overlay) == [*identified.joint_names, "wrist_3-flange"]
    root = ET.fromstring(identified.urdf.text)
    for joint in root.findall("joint"):
        entry = overlay.get(str(joint.get("name")))
        origin = joint.find("origin")
        if entry is None or origin is None:
            continue
        origin.set("xyz", " ".join(repr(entry[k]) for k in ("x", "y", "z")))
        origin.set("rpy", " ".join(repr(entry[k]) for k in ("roll", "pitch", "yaw")))
    q = random_poses(identified, 300, np.random.default_rng(8))
    found = urdf_flange(ET.tostring(root, encoding="unicode"), identified.joint_names, q,
                        "tool0", "world")
    np.testing.assert_allclose(found, identified.flange_transforms(q), rtol=0.0, atol=1e-9)


def test_export_cli_writes_the_calibrated_urdf_with_its_names(tmp_path: Path) -> None:
    """`twin calibrate` on a UR5e given as a URDF, then `twin export --robot ur5e.urdf --format
    urdf`: the file keeps every joint and link name and its Pinocchio FK is the result's model;
    without --robot the result's own robot is used, to the same bytes; a --robot with another
    tip link or loaded in another parametrisation is another robot, refused."""
    robot = load_robot(URDFS["ur5e"])
    true = _perturbed(robot, 9)
    q = random_poses(robot, 60, np.random.default_rng(10))
    data = synthesize(true, q, PORT_M, 1e-5, np.random.default_rng(11))
    result = calibrate(robot, data, PORT_M, method="lm", seed=0)
    write_json(tmp_path / "result.json", result_to_dict(result))
    out = tmp_path / "calibrated.urdf"
    assert main(["export", str(tmp_path / "result.json"), "--robot", str(URDFS["ur5e"]),
                 "--format", "urdf", "--out", str(out)]) == 0
    identified = result.identified_geometry
    found = urdf_flange(out.read_text(), robot.joint_names, q, "tool0", "world")
    # The result file keeps 1e-6 mm and 1e-6 degree: that is the agreement to expect.
    np.testing.assert_allclose(found[:, :3, 3], identified.flange_transforms(q)[:, :3, 3],
                               rtol=0.0, atol=1e-7)
    assert _elements(out.read_text()) == _elements(URDFS["ur5e"].read_text())
    assert json.loads((tmp_path / "result.json").read_text())["robot"]["parametrisation"] == [
        "dh", "hayati", "hayati", "dh", "dh", "dh"]
    alone = tmp_path / "alone.urdf"
    assert main(["export", str(tmp_path / "result.json"), "--format", "urdf", "--out",
                 str(alone)]) == 0
    assert alone.read_bytes() == out.read_bytes()
    code = main(["export", str(tmp_path / "result.json"), "--robot", str(URDFS["ur5e"]),
                 "--format", "urdf", "--out", str(tmp_path / "other.urdf"), "--tip-link",
                 "flange"])
    assert code == 2 and not (tmp_path / "other.urdf").exists()
    with pytest.raises(InputError, match="parametrisation"):
        load_result_delta(tmp_path / "result.json",
                          load_urdf(URDFS["ur5e"], parametrisation="dh"))


def test_reparametrised_urdf_robot_writes_back_the_same_urdf() -> None:
    """Re-expressing a URDF robot in another parametrisation keeps where its URDF frames sit:
    both write back the same calibrated URDF (FK to 1e-9 m)."""
    auto = _perturbed(load_robot(URDFS["irb120"]), 12)
    mdh = auto.reparametrised("mdh")
    assert mdh.structure.parametrisation == ("mdh",) * 6
    q = random_poses(auto, 200, np.random.default_rng(13))
    first = urdf_flange(export_text(auto, "urdf"), auto.joint_names, q, "tool0")
    second = urdf_flange(export_text(mdh, "urdf"), auto.joint_names, q, "tool0")
    np.testing.assert_allclose(second, first, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(_link_frames(export_text(mdh, "urdf")),
                               _link_frames(export_text(auto, "urdf")), atol=1e-9)


def _link_frames(text: str) -> np.ndarray:
    """Every body frame of a URDF at q = 0 by Pinocchio, shape (k, 4, 4)."""
    model = pin.buildModelFromXML(text)
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    return np.array([frame.homogeneous for frame in data.oMf])
