"""Exports of the identified robot load in their tools and agree with the identified table."""

from __future__ import annotations

import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from twin.calibration.pipeline import calibrate
from twin.cli import main
from twin.dataset import Measurements
from twin.export import FORMATS, export_text
from twin.geometry.kinematics import flange_transform
from twin.io.results import result_to_dict, write_json
from twin.io.robot_file import load_robot, parse_robot
from twin.robot import RobotModel

N_POSES = 1000


@pytest.fixture(scope="module")
def identified(irb120: RobotModel, measurements: Measurements, port_m: np.ndarray) -> RobotModel:
    """The IRB 120 identified by LM from core-made data."""
    return calibrate(irb120, measurements, port_m, method="lm", seed=0).identified_geometry


@pytest.fixture(scope="module")
def poses(irb120: RobotModel) -> np.ndarray:
    rng = np.random.default_rng(9)
    return rng.uniform(irb120.lower_rad, irb120.upper_rad, (N_POSES, irb120.n_joints))


def _assert_same_poses(expected: np.ndarray, found: np.ndarray, atol: float = 1e-9) -> None:
    np.testing.assert_allclose(found[:, :3, 3], expected[:, :3, 3], rtol=0.0, atol=atol)
    np.testing.assert_allclose(found[:, :3, :3], expected[:, :3, :3], rtol=0.0, atol=atol)


def _as_written(dh: np.ndarray) -> np.ndarray:
    """A D-H table as a model file states it: lengths to 1 µm, angles to 1e-6 degree."""
    return np.vstack([np.round(dh[:2] * 1e3, 3) / 1e3,
                      np.deg2rad(np.round(np.rad2deg(dh[2:]), 6))])


def test_dh_export_reads_back(identified: RobotModel, poses: np.ndarray) -> None:
    """The dh export is a model file of the identified table rounded to 1 µm and 1e-6 degree:
    its FK equals that rounded table's to 1e-9 m; against the unrounded table the flange moves
    by no more than the 2n half-µm lengths and 2n half-1e-6° angles (at 1 m) can add up to."""
    robot = parse_robot(tomllib.loads(export_text(identified, "dh")), "export.toml")
    np.testing.assert_allclose(robot.dh, _as_written(identified.dh), rtol=0.0, atol=1e-15)
    exported = robot.flange_transforms(poses)
    written = flange_transform(identified.structure, _as_written(identified.dh), poses)
    _assert_same_poses(written, exported)
    shift = np.linalg.norm(exported[:, :3, 3] - identified.flange_transforms(poses)[:, :3, 3],
                           axis=1)
    n, reach = identified.n_joints, 1.0
    worst = 2 * n * 0.5e-6 + 2 * n * np.deg2rad(0.5e-6) * reach
    assert np.max(shift) <= worst


def test_urdf_export_loads_in_pinocchio(identified: RobotModel, poses: np.ndarray) -> None:
    """Pinocchio loads the URDF; its `tool0` frame equals the identified FK to 1e-9 m."""
    model = pin.buildModelFromXML(export_text(identified, "urdf"))
    data = model.createData()
    frame = model.getFrameId("tool0")
    assert frame < model.nframes
    found = []
    for q in poses:
        pin.framesForwardKinematics(model, data, q)
        found.append(data.oMf[frame].homogeneous.copy())
    _assert_same_poses(identified.flange_transforms(poses), np.array(found))


def test_mjcf_export_loads_in_mujoco(identified: RobotModel, poses: np.ndarray) -> None:
    """MuJoCo compiles the MJCF; its `flange` site equals the identified FK to 1e-9 m."""
    model = mujoco.MjModel.from_xml_string(export_text(identified, "mjcf"))
    data = mujoco.MjData(model)
    site = model.site("flange").id
    assert model.nq == identified.n_joints
    found = np.zeros((len(poses), 4, 4))
    for row, q in enumerate(poses):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        found[row, :3, :3] = data.site_xmat[site].reshape(3, 3)
        found[row, :3, 3] = data.site_xpos[site]
    _assert_same_poses(identified.flange_transforms(poses), found)
    np.testing.assert_allclose(model.jnt_range, np.stack([identified.lower_rad,
                                                         identified.upper_rad], axis=1))


@pytest.mark.parametrize("format_name", FORMATS)
def test_export_cli_writes_each_format(
    tmp_path: Path, format_name: str, irb120: RobotModel, measurements: Measurements,
    port_m: np.ndarray, identified: RobotModel,
) -> None:
    """`twin export` writes the identified robot from a result file in every format (UR's file
    only for a UR: an IRB 120 is refused and nothing written)."""
    result = calibrate(irb120, measurements, port_m, method="lm", seed=0)
    write_json(tmp_path / "result.json", result_to_dict(result))
    out = tmp_path / f"identified.{format_name}"
    assert main(["export", str(tmp_path / "result.json"), "--format", format_name,
                 "--out", str(out)]) == (2 if format_name == "ur-calibration" else 0)
    if format_name == "ur-calibration":
        assert not out.exists()
    elif format_name == "xacro":
        names = [e.get("name") for e in ET.parse(out).getroot()]
        assert "joint_1_origin_xyz" in names and "link_6_tool0_origin_rpy" in names
    elif format_name == "dh":
        exported = load_robot(out)
        # The result file holds 1e-6 mm and degree, the model file 1 µm and 1e-6 degree.
        np.testing.assert_allclose(exported.dh[:2], identified.dh[:2], rtol=0.0, atol=0.6e-6)
        np.testing.assert_allclose(exported.dh[2:], identified.dh[2:], rtol=0.0,
                                   atol=np.deg2rad(1.1e-6))
        assert exported.name == f"{irb120.name} (identified)"
    elif format_name == "urdf":
        assert pin.buildModelFromUrdf(str(out)).existFrame("tool0")
    elif format_name == "yaml":
        assert "kinematics:" in out.read_text() and "joint_6:" in out.read_text()
    else:
        assert mujoco.MjModel.from_xml_path(str(out)).site("flange").id >= 0


def test_export_cli_rejects_unknown_format(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An unknown --format exits 2 with one line naming the choices, and writes nothing."""
    result = tmp_path / "result.json"
    result.write_text('{"delta": {"a": [0,0,0,0,0,0], "d": [0,0,0,0,0,0], '
                      '"alpha": [0,0,0,0,0,0], "theta": [0,0,0,0,0,0]}}')
    out = tmp_path / "out.sdf"
    assert main(["export", str(result), "--format", "sdf", "--out", str(out)]) == 2
    error = capsys.readouterr().err.strip()
    assert error.count("\n") == 0 and "one of dh, urdf, yaml, mjcf" in error
    assert not out.exists()
