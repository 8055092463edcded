"""UR's calibration file and xacro descriptions: read back by independent readers (PyYAML and a
forward kinematics of UR's convention written here, xacro and Pinocchio) and held to the
identified model; a xacro UR description calibrated end to end."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import Refusals
from scipy.spatial.transform import Rotation

from twin.cli import main
from twin.export import export_text
from twin.export.ur_calibration import UrCalibrationWarning, ur_origins
from twin.io.identified import load_result_delta
from twin.io.measurements import write_measurements
from twin.io.robot_file import load_robot
from twin.robot import RobotModel, random_poses
from twin.synthetic import synthesize

pytest.importorskip("pinocchio")
xacro = pytest.importorskip("xacro")

ROOT = Path(__file__).resolve().parents[1]
UR5E = ROOT / "models" / "ur5e" / "ur5e.urdf"
ENTRIES = {"shoulder_pan_joint": "shoulder", "shoulder_lift_joint": "upper_arm",
           "elbow_joint": "forearm", "wrist_1_joint": "wrist_1", "wrist_2_joint": "wrist_2",
           "wrist_3_joint": "wrist_3"}
BASE = """# my robot's calibration, extracted by ur_calibration on 2024-05-01
kinematics:
  shoulder:
    x: 0
    y: 0
    z: 0.1625
    roll: 0
    pitch: 0
    yaw: 0
  upper_arm:
    x: 0
    y: 0
    z: 0
    roll: 1.570796327
    pitch: 0
    yaw: 0
  forearm:
    x: -0.425
    y: 0
    z: 0
    roll: 0
    pitch: 0
    yaw: 0
  wrist_1:
    x: -0.3922
    y: 0
    z: 0.1333
    roll: 0
    pitch: 0
    yaw: 0
  wrist_2:
    x: 0
    y: -0.0997
    z: -2.044881182297852e-11
    roll: 1.570796327
    pitch: 0
    yaw: 0
  wrist_3:
    x: 0
    y: 0.09959999999999999
    z: -2.042830148012698e-11
    roll: 1.570796326589793
    pitch: 3.141592653589793
    yaw: 3.141592653589793
  hash: calib_12788084448423163542  # the robot's own
"""
"""ur_description's default_kinematics.yaml for the UR5e (Universal_Robots_ROS2_Description
2221ec0, BSD-3-Clause: numbers, see models/ur5e/README.md) with comments of a user's."""


def origin(xyz: list[float], rpy: list[float]) -> np.ndarray:
    """A URDF origin: translation, then R = Rz(yaw) Ry(pitch) Rx(roll)."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("ZYX", rpy[::-1]).as_matrix()
    T[:3, 3] = xyz
    return T


def ur_fk(kinematics: dict, q: np.ndarray) -> np.ndarray:
    """tool0 in world for UR's file: ur_macro.xacro's chain (world → base_link → base_link_
    inertia turned by π → the six calibrated joints → flange → tool0, the fixed ones read from
    models/ur5e/ur5e.urdf), each joint turning about its z."""
    fixed = {j.get("name"): j.find("origin") for j in ET.parse(UR5E).getroot().iter("joint")}

    def constant(name: str) -> np.ndarray:
        element = fixed[name]
        return origin([float(v) for v in element.get("xyz").split()],  # type: ignore[union-attr]
                      [float(v) for v in element.get("rpy").split()])  # type: ignore[union-attr]

    poses = []
    for row in q:
        T = constant("base_joint") @ constant("base_link-base_link_inertia")
        for k, entry in enumerate(ENTRIES.values()):
            values = kinematics[entry]
            T = T @ origin([values["x"], values["y"], values["z"]],
                           [values["roll"], values["pitch"], values["yaw"]])
            T = T @ origin([0, 0, 0], [0, 0, row[k]])
        poses.append(T @ constant("wrist_3-flange") @ constant("flange-tool0"))
    return np.array(poses)


def _perturbed(robot: RobotModel, seed: int, flange_off_axis: float = 0.0) -> RobotModel:
    """The robot with mm / mrad errors on every entry but the last row's a and α (which UR's
    file cannot hold), those set to ``flange_off_axis`` (m, rad)."""
    rng = np.random.default_rng(seed)
    delta = rng.uniform(-1, 1, (4, 6)) * np.where(robot.is_length, 1e-3, 1e-3)
    delta[0, 5] = delta[2, 5] = flange_off_axis
    return robot.perturbed(delta)


@pytest.mark.slow
def test_ur_file_is_the_identified_robot() -> None:
    """A calibrated UR5e in UR's layout, read by PyYAML and turned into forward kinematics by
    UR's convention (this test's), is the identified robot's tool0 to 1e-9 m on 1000 poses."""
    identified = _perturbed(load_robot(UR5E), 1)
    document = yaml.safe_load(export_text(identified, "ur-calibration"))
    kinematics = document["kinematics"]
    assert list(kinematics) == [*ENTRIES.values(), "hash"]
    assert all(list(kinematics[e]) == ["x", "y", "z", "roll", "pitch", "yaw"]
               for e in ENTRIES.values())
    assert re.fullmatch(r"twin_[0-9a-f]{16}", kinematics["hash"])
    q = random_poses(identified, 1000, np.random.default_rng(2))
    found, wanted = ur_fk(kinematics, q), identified.flange_transforms(q)
    np.testing.assert_allclose(found[:, :3, 3], wanted[:, :3, 3], rtol=0, atol=1e-9)
    np.testing.assert_allclose(found[:, :3, :3], wanted[:, :3, :3], rtol=0, atol=1e-9)


def test_flange_off_the_last_axis() -> None:
    """A flange moved 1 mm and 1 mrad off the last axis (which UR's file has no place for): the
    export warns with the TCP offset that holds it, and the file's chain with that offset is the
    identified robot to 1e-9 m; without it, off by about the millimetre."""
    robot = load_robot(UR5E)
    moved = _perturbed(robot, 3, 1e-3)
    with pytest.warns(UrCalibrationWarning, match="add it to the TCP"):
        text = export_text(moved, "ur-calibration")
    remainder = ur_origins(moved).tcp_remainder
    q = random_poses(moved, 200, np.random.default_rng(4))
    file_fk = ur_fk(yaml.safe_load(text)["kinematics"], q)
    np.testing.assert_allclose(file_fk @ remainder, moved.flange_transforms(q), atol=1e-9)
    apart = np.linalg.norm(file_fk[:, :3, 3] - moved.flange_transforms(q)[:, :3, 3], axis=1)
    assert 5e-4 < apart.max() < 5e-3


def _ur_xacro(folder: Path) -> Path:
    """A UR5e description in xacro that takes its joint origins from a kinematics file given as
    an argument, as ur_description does: models/ur5e/ur5e.urdf with the six revolute origins
    read from ``xacro.load_yaml``."""
    text = UR5E.read_text()
    text = text.replace('<robot name="ur5e">', '<robot name="ur5e" '
                        'xmlns:xacro="http://www.ros.org/wiki/xacro">\n'
                        '  <xacro:arg name="kinematics" default="default_kinematics.yaml"/>\n'
                        "  <xacro:property name=\"kin\" value=\"${xacro.load_yaml("
                        "'$(arg kinematics)')['kinematics']}\"/>")
    for joint, entry in ENTRIES.items():
        pattern = re.compile(rf'(<joint name="{joint}" type="revolute">.*?)<origin [^>]*/>', re.S)
        values = {k: f"${{kin['{entry}']['{k}']}}" for k in ("x", "y", "z", "roll", "pitch",
                                                              "yaw")}
        text = pattern.sub(lambda m, v=values: m[1] + f'<origin xyz="{v["x"]} {v["y"]} '
                           f'{v["z"]}" rpy="{v["roll"]} {v["pitch"]} {v["yaw"]}"/>', text)
    path = folder / "ur5e.urdf.xacro"
    path.write_text(text)
    (folder / "default_kinematics.yaml").write_text(BASE)
    return path


def test_xacro_description_reads_as_its_urdf(tmp_path: Path) -> None:
    """The xacro UR5e with UR's default kinematics is the URDF's robot to 1e-12 m."""
    described = _ur_xacro(tmp_path)
    robot = load_robot(described, xacro_args={"kinematics": str(tmp_path /
                                                                "default_kinematics.yaml")})
    urdf = load_robot(UR5E)
    q = random_poses(urdf, 300, np.random.default_rng(5))
    np.testing.assert_allclose(robot.flange_transforms(q), urdf.flange_transforms(q), atol=1e-12)
    assert robot.joint_names == urdf.joint_names


@pytest.mark.slow
def test_xacro_ur_calibrates_end_to_end(tmp_path: Path) -> None:
    """Cable data of a perturbed UR5e, calibrated with --robot ur5e.urdf.xacro --xacro-arg,
    exported in UR's layout over the user's file: the hash and the comments are the user's, the
    user's file is untouched, and the description expanded by xacro with the new file and read
    by Pinocchio, with the TCP offset the export names (the noise's few 1e-8 m of the flange
    off the last axis), is the identified robot to 1e-9 m."""
    import pinocchio as pin

    described = _ur_xacro(tmp_path)
    base = tmp_path / "default_kinematics.yaml"
    flags = ["--robot", str(described), "--xacro-arg", f"kinematics:={base}"]
    nominal = load_robot(described, xacro_args={"kinematics": str(base)})
    rng = np.random.default_rng(6)
    data = synthesize(_perturbed(nominal, 7), random_poses(nominal, 200, rng),
                      [0.6, -0.4, 0.1], 1e-6, rng)
    write_measurements(tmp_path / "m.csv", data)
    assert main(["calibrate", str(tmp_path / "m.csv"), *flags, "--port", "600,-400,100",
                 "--json", str(tmp_path / "r.json")]) == 0
    out = tmp_path / "my_calibration.yaml"
    assert main(["export", str(tmp_path / "r.json"), *flags, "--format", "ur-calibration",
                 "--base", str(base), "--out", str(out)]) == 0
    written = out.read_text()
    assert base.read_text() == BASE
    assert "# my robot's calibration" in written and "# the robot's own" in written
    assert yaml.safe_load(written)["kinematics"]["hash"] == "calib_12788084448423163542"
    identified = nominal.perturbed(load_result_delta(tmp_path / "r.json", nominal))
    remainder = ur_origins(identified).tcp_remainder
    assert np.abs(remainder - np.eye(4)).max() < 1e-6
    urdf = xacro.process_file(str(described), mappings={"kinematics": str(out)}).toxml()
    model = pin.buildModelFromXML(urdf)
    data_pin = model.createData()
    frame = model.getFrameId("tool0")
    q = random_poses(identified, 200, np.random.default_rng(8))
    for row, wanted in zip(q, identified.flange_transforms(q), strict=True):
        pin.framesForwardKinematics(model, data_pin, row)
        np.testing.assert_allclose(data_pin.oMf[frame].homogeneous @ remainder, wanted,
                                   atol=1e-9)


def test_xacro_properties_export(tmp_path: Path) -> None:
    """--format xacro: a description that includes the properties file and writes its joint
    origins from them, expanded by xacro and read by Pinocchio, is the identified robot."""
    import pinocchio as pin

    identified = _perturbed(load_robot(UR5E), 9)
    (tmp_path / "calibration.xacro").write_text(export_text(identified, "xacro"))
    text = UR5E.read_text().replace('<robot name="ur5e">', '<robot name="ur5e" xmlns:xacro='
                                    '"http://www.ros.org/wiki/xacro">\n  <xacro:include '
                                    'filename="calibration.xacro"/>')
    for joint in (*ENTRIES, "wrist_3-flange"):
        pattern = re.compile(rf'(<joint name="{joint}" type="\w+">.*?)<origin [^>]*/>', re.S)
        name = joint.replace("-", "_")
        text = pattern.sub(lambda m, n=name: m[1] + f'<origin xyz="${{{n}_origin_xyz}}" '
                           f'rpy="${{{n}_origin_rpy}}"/>', text)
    (tmp_path / "arm.urdf.xacro").write_text(text)
    model = pin.buildModelFromXML(xacro.process_file(str(tmp_path / "arm.urdf.xacro")).toxml())
    data = model.createData()
    q = random_poses(identified, 100, np.random.default_rng(10))
    for row, wanted in zip(q, identified.flange_transforms(q), strict=True):
        pin.framesForwardKinematics(model, data, row)
        np.testing.assert_allclose(data.oMf[model.getFrameId("tool0")].homogeneous, wanted,
                                   atol=1e-9)


def test_find_resolves_packages_without_ros(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                            refusals: Refusals) -> None:
    """$(find PKG) resolves through ROS_PACKAGE_PATH without ROS; a package found nowhere is one
    line naming it, exit 2."""
    package = tmp_path / "src" / "my_robot_description"
    (package / "urdf").mkdir(parents=True)
    (package / "package.xml").write_text("<package><name>my_robot_description</name></package>")
    (package / "urdf" / "arm.urdf").write_text(UR5E.read_text())
    top = tmp_path / "cell.urdf.xacro"
    top.write_text('<robot name="cell" xmlns:xacro="http://www.ros.org/wiki/xacro">\n'
                   '  <xacro:include filename="$(find my_robot_description)/urdf/arm.urdf"/>\n'
                   "</robot>\n")
    monkeypatch.delenv("AMENT_PREFIX_PATH", raising=False)
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(tmp_path / "src"))
    robot = load_robot(top)
    q = random_poses(robot, 50, np.random.default_rng(11))
    np.testing.assert_allclose(robot.flange_transforms(q), load_robot(UR5E).flange_transforms(q),
                               atol=1e-12)
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(tmp_path / "elsewhere"))
    refusals.cli(["plan", "--robot", top, "--port", "600,-400,100", "--poses", "30",
                  "--joint-limits-only", "--out", tmp_path / "p.csv"], [top],
                 "no package 'my_robot_description'")
    refusals.cli(["plan", "--port", "600,-400,100", "--poses", "30", "--xacro-arg", "a:=1",
                  "--joint-limits-only", "--out", tmp_path / "p.csv"], [], "--xacro-arg")
