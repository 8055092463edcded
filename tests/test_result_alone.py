"""A result file is usable alone: it carries the robot it was identified for, so predict,
export and compensate need no --robot (a TOML robot, a URDF robot, a 7-joint arm), a robot
given anyway must be that one, and what the data could not see leaves at the nominal."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import Refusals
from scipy.linalg import null_space

from twin.calibration.pipeline import calibrate
from twin.cli import main
from twin.io.identified import load_result
from twin.io.measurements import write_measurements
from twin.io.results import result_to_dict, write_json
from twin.io.robot_file import default_robot, load_robot, robot_digest, robot_to_toml
from twin.report.text import format_result
from twin.robot import RobotModel, random_poses
from twin.synthetic import synthesize
from twin.units import m_to_mm

MODELS = Path(__file__).resolve().parents[1] / "models"
PORT_M = np.array([0.6, -0.4, 0.1])
ROBOTS = {"irb120 toml": None, "ur5e urdf": MODELS / "ur5e" / "ur5e.urdf",
          "fr3 urdf (7 joints)": MODELS / "fr3" / "fr3.urdf"}


def _case(tmp_path: Path, source: Path | None) -> tuple[RobotModel, Path, Path]:
    """A robot, a result of it written by `twin calibrate`, and the measurements."""
    robot = default_robot() if source is None else load_robot(source)
    rng = np.random.default_rng(5)
    delta = rng.uniform(-1, 1, robot.dh.shape) * np.where(robot.is_length, 5e-4,
                                                          np.deg2rad(0.05))
    data = synthesize(robot.perturbed(delta), random_poses(robot, 120, rng), PORT_M, 1e-5, rng)
    csv = tmp_path / "m.csv"
    write_measurements(csv, data)
    port = ",".join(f"{v:g}" for v in m_to_mm(PORT_M))
    argv = ["calibrate", str(csv), "--port", port, "--json", str(tmp_path / "r.json")]
    assert main(argv + ([] if source is None else ["--robot", str(source)])) == 0
    return robot, tmp_path / "r.json", csv


@pytest.mark.parametrize("name", list(ROBOTS))
def test_predict_export_compensate_need_no_robot(name: str, tmp_path: Path) -> None:
    """Each command runs on the result alone; the prediction is the result's model at the
    poses, the export's table the identified one, and `load_result` rebuilds the same
    robot (same digest) with nothing but the file."""
    robot, result, csv = _case(tmp_path, ROBOTS[name])
    loaded = load_result(result)
    assert robot_digest(loaded.robot) == robot_digest(robot)
    assert main(["predict", "--identified", str(result), "--joints", str(csv),
                 "--out", str(tmp_path / "p.csv")]) == 0
    lines = (tmp_path / "p.csv").read_text().splitlines()
    assert len(lines) == 121
    assert main(["export", str(result), "--format", "dh", "--out",
                 str(tmp_path / "id.toml")]) == 0
    exported = load_robot(tmp_path / "id.toml")
    # A model file keeps 1 µm and 1e-6 degree.
    np.testing.assert_allclose(exported.dh, loaded.model.table(loaded.x), rtol=0, atol=5e-7)
    assert main(["compensate", "--identified", str(result), "--joints", str(csv),
                 "--out", str(tmp_path / "c.csv")]) == 0
    assert len((tmp_path / "c.csv").read_text().splitlines()) == 121


def test_a_robot_given_must_be_the_results(tmp_path: Path, refusals: Refusals) -> None:
    """The same robot given anyway is fine; another one is refused in one line naming both,
    nothing written."""
    robot, result, _ = _case(tmp_path, None)
    same = tmp_path / "same.toml"
    same.write_text(robot_to_toml(robot))
    assert main(["export", str(result), "--robot", str(same), "--format", "dh", "--out",
                 str(tmp_path / "a.toml")]) == 0
    other = tmp_path / "other.toml"
    other.write_text(robot_to_toml(robot.perturbed(np.r_[0.0, 0.01, np.zeros(22)])))
    refusals.cli(["export", result, "--robot", other, "--format", "dh", "--out",
                  tmp_path / "b.toml"], [result, other],
                 "found a result identified for another nominal table of ABB IRB 120")
    assert not (tmp_path / "b.toml").exists()


def test_unseen_directions_leave_at_the_nominal(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    """A cable at the flange centre with a known port cannot see α6 and θ6: however the truth
    has them, the result file says 0 to 1e-9 rad (1e-6 degree is the file's rounding), and so
    does every format exported from it, with a warning naming them; the table's entries in a
    held direction are marked, the JSON's say so."""
    robot = default_robot()
    rng = np.random.default_rng(3)
    delta = np.zeros((4, 6))
    delta[2, 5], delta[3, 5] = np.deg2rad(0.5), np.deg2rad(-3.0)
    data = synthesize(robot.perturbed(delta), random_poses(robot, 120, rng), PORT_M, 1e-5, rng)
    result = calibrate(robot, data, PORT_M)
    assert abs(result.delta[2, 5]) < 1e-9 and abs(result.delta[3, 5]) < 1e-9
    write_json(tmp_path / "r.json", result_to_dict(result))
    document = json.loads((tmp_path / "r.json").read_text())
    assert document["delta"]["alpha"][5] == 0.0 and document["delta"]["theta"][5] == 0.0
    assert main(["export", str(tmp_path / "r.json"), "--format", "dh", "--out",
                 str(tmp_path / "id.toml")]) == 0
    assert abs(load_robot(tmp_path / "id.toml").dh[3, 5]) < 1e-9
    warned = capsys.readouterr().err
    assert "the data did not see alpha6, theta6" in warned and "held at the nominal" in warned
    # Referee of the "held" marks: scipy's null space of the Jacobian at the nominal, scaled
    # by the hold's weights; an unknown more than 1% in it is seen only in a combination.
    model, unseen = result.model, result.unseen
    assert unseen is not None
    _, jacobian = model.jacobian(np.zeros(model.n_params), data.subset(result.train_rows))
    null = null_space(jacobian * unseen.scale, rcond=1e-8)
    referee = {name for name, part in zip(model.names, np.sum(null**2, axis=1), strict=True)
               if part > 0.01}
    assert {"alpha6", "theta6", "a5", "theta5"} <= referee
    held = {entry["name"] for entry in document["unknowns"]["parameters"] if entry["held"]}
    assert held == referee
    rows = format_result(result).split("Identified D-H errors")[1].splitlines()[2:8]
    marked = {f"{key}{joint}" for joint, row in enumerate(rows, start=1)
              for key, cell in zip(("a", "d", "alpha", "theta"), row.split()[1:], strict=True)
              if cell.endswith("~")}
    assert marked == referee


def _orientation_error_deg(robot: RobotModel, truth: RobotModel, q: np.ndarray) -> float:
    """RMS angle between two robots' flange frames over poses q (k, n), degrees."""
    from scipy.spatial.transform import Rotation

    relative = np.swapaxes(robot.flange_transforms(q)[:, :3, :3], -1, -2) \
        @ truth.flange_transforms(q)[:, :3, :3]
    return float(np.degrees(np.sqrt(np.mean(Rotation.from_matrix(relative).magnitude() ** 2))))


def test_what_the_data_cannot_tell_from_zero_stays_at_the_nominal() -> None:
    """Small errors (as the README's example, where LM put θ6 at −0.66° ± 0.51°, the truth
    +0.05°): the weak directions (θ6 through a6 of 0.2 mm; d5 − α5 and a5 + θ5 of the wrist) the
    data cannot tell from zero are held, and the flange frame turns far less from the truth's
    than the method's own answer's (the truth the referee); a large θ6 the data do see (5°
    through a6 of 4 mm) is kept and recovered."""
    robot = default_robot()
    rng = np.random.default_rng(4)
    q_ws = random_poses(robot, 1000, np.random.default_rng(9))
    for theta6_deg, a6_mm in ((0.05, 0.2), (5.0, 4.0)):
        delta = np.zeros((4, 6))
        delta[0, :5] = np.array([0.3, -0.4, 0.5, 0.2, -0.3]) * 1e-3
        delta[1, :5] = np.array([0.2, -0.3, 0.4, 0.1, 0.2]) * 1e-3
        delta[2, :5] = np.deg2rad([0.05, -0.08, 0.1, -0.06, 0.07])
        delta[3, :5] = np.deg2rad([0.04, 0.06, -0.05, 0.08, -0.03])
        delta[0, 5], delta[3, 5] = a6_mm * 1e-3, np.deg2rad(theta6_deg)
        truth = robot.perturbed(delta)
        data = synthesize(truth, random_poses(robot, 120, rng), PORT_M, 1e-5, rng)
        result = calibrate(robot, data, PORT_M)
        identified = robot.perturbed(result.delta)
        if theta6_deg < 1:
            assert result.held is not None and abs(result.delta[3, 5]) < 1e-9
            own = robot.perturbed(result.model.table(result.held.method_x) - robot.dh)
            assert _orientation_error_deg(identified, truth, q_ws) \
                < 0.5 * _orientation_error_deg(own, truth, q_ws)
        else:
            assert result.delta[3, 5] == pytest.approx(delta[3, 5], abs=np.deg2rad(0.2))
