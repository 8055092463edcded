"""Full-pose compensation targets: a TCP's pose (quaternion or angles) in a work object with a
tool, on the configuration given, corrected and run on the true robot."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import Refusals
from scipy.spatial.transform import Rotation

from twin.cli import main
from twin.compensation.configuration import configuration
from twin.compensation.poses import controller_tool0
from twin.compensation.targets import reachable_targets
from twin.io.identified import load_result_delta
from twin.robot import RobotModel

TOOL = ([10.0, -20.0, 150.0], Rotation.from_euler("y", 20, degrees=True))
WOBJ = ([400.0, -50.0, 100.0], Rotation.from_euler("z", 40, degrees=True))


def _pose(trans_mm: list[float], rotation: Rotation) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = rotation.as_matrix(), np.asarray(trans_mm) / 1000.0
    return T


def _flag(trans_mm: list[float], rotation: Rotation) -> str:
    return ",".join(repr(float(v)) for v in [*trans_mm, *rotation.as_quat(scalar_first=True)])


@pytest.fixture()
def result(csv_path: Path, tmp_path: Path) -> Path:
    path = tmp_path / "result.json"
    assert main(["calibrate", str(csv_path), "--port", "600,-400,100", "--json", str(path)]) == 0
    return path


def _targets(irb120: RobotModel, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Random joints, the TCP pose they give in the work object, and their configuration."""
    q, _ = reachable_targets(irb120, n, np.random.default_rng(3))
    chain = controller_tool0(irb120) @ _pose(*TOOL)  # type: ignore[operator]
    in_wobj = np.linalg.inv(_pose(*WOBJ)) @ irb120.flange_transforms(q) @ chain
    return q, in_wobj, configuration(irb120, q)


def test_tcp_targets_in_a_work_object(irb120: RobotModel, true_robot: RobotModel, result: Path,
                                      tmp_path: Path) -> None:
    """Quaternion and angle targets alike: the corrected joints are on each target's
    configuration, put the true robot's flange within twice the identified model's flange error
    there (five times closer than the nominal joints), and its TCP within twice the model's TCP
    error: an orientation the cable could not see (θ6, α6) moves a TCP off the flange axis by
    whatever the calibration left there, and no compensation can do better than its model."""
    q, in_wobj, conf = _targets(irb120, 30)
    quaternion = Rotation.from_matrix(in_wobj[:, :3, :3]).as_quat(scalar_first=True)
    angles = Rotation.from_matrix(in_wobj[:, :3, :3]).as_euler("xyz", degrees=True)
    outputs = []
    for columns, values in (("qw,qx,qy,qz", quaternion), ("rx,ry,rz", angles)):
        rows = [",".join(repr(float(x)) for x in [*(T[:3, 3] * 1000), *v, *c]) for T, v, c in
                zip(in_wobj, values, conf, strict=True)]
        path = tmp_path / f"targets_{len(outputs)}.csv"
        path.write_text(f"x,y,z,{columns},cf1,cf4,cf6,cfx\n" + "\n".join(rows) + "\n")
        out = tmp_path / f"corrected_{len(outputs)}.csv"
        assert main(["compensate", "--identified", str(result), "--targets", str(path),
                     "--tool", _flag(*TOOL), "--wobj", _flag(*WOBJ), "--out", str(out)]) == 0
        outputs.append(np.loadtxt(out, delimiter=",", skiprows=1, usecols=range(6)))
    np.testing.assert_allclose(outputs[0], outputs[1], atol=2e-6)
    corrected = np.deg2rad(outputs[0])
    assert np.array_equal(configuration(irb120, corrected)[:, 3], conf[:, 3])
    identified = irb120.perturbed(load_result_delta(result, irb120))
    chain = controller_tool0(irb120) @ _pose(*TOOL)  # type: ignore[operator]
    for point in (np.eye(4), chain):
        wanted = (irb120.flange_transforms(q) @ point)[:, :3, 3]
        reached = (true_robot.flange_transforms(corrected) @ point)[:, :3, 3]
        unmoved = (true_robot.flange_transforms(q) @ point)[:, :3, 3]
        believed = (identified.flange_transforms(q) @ point)[:, :3, 3]
        after = np.linalg.norm(reached - wanted, axis=1)
        assert np.all(after <= 2 * np.linalg.norm(believed - unmoved, axis=1) + 1e-6)
    flange = np.eye(4)[None]
    before = np.linalg.norm((true_robot.flange_transforms(q) - irb120.flange_transforms(q)
                             )[:, :3, 3], axis=1)
    after = np.linalg.norm((true_robot.flange_transforms(corrected)
                            - irb120.flange_transforms(q) @ flange)[:, :3, 3], axis=1)
    assert np.min(before) > 5 * np.max(after)


def test_pose_targets_refusals(irb120: RobotModel, result: Path, tmp_path: Path,
                               refusals: Refusals) -> None:
    """A tool without an orientation, two orientations, a quaternion that is not a unit one, a
    named tool with --targets: one line each, exit 2, nothing written."""
    out = tmp_path / "c.csv"
    base = ["compensate", "--identified", result, "--out", out]
    positions = tmp_path / "p.csv"
    positions.write_text("x,y,z\n400,0,500\n")
    refusals.cli([*base, "--targets", positions, "--tool", "0,0,100"], [positions],
                 "without an orientation")
    both = tmp_path / "b.csv"
    both.write_text("x,y,z,qw,qx,qy,qz,rx,ry,rz\n400,0,500,1,0,0,0,0,0,0\n")
    refusals.cli([*base, "--targets", both], [both], "one orientation per row")
    bad = tmp_path / "q.csv"
    bad.write_text("x,y,z,qw,qx,qy,qz\n400,0,500,1,0,0,0\n400,0,500,0.9,0,0,0\n")
    refusals.cli([*base, "--targets", bad], [bad], "line 3")
    named = tmp_path / "n.csv"
    named.write_text("x,y,z,qw,qx,qy,qz\n400,0,500,0,0,1,0\n")
    refusals.cli([*base, "--targets", named, "--tool", "gun=0,0,100"], [named], "named --tool")
    assert not out.exists()
