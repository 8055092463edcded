"""Any serial arm end to end: a UR5e given only as a URDF, a 7-axis arm and a 4-axis chain run
through simulate → calibrate → predict → compensate in the MuJoCo twin, and the UR5e's
calibration goes back into its URDF.

The referee of every number is the twin's truth and, for the calibration, scipy's
``least_squares`` on the same residual, run here; the bound is the Cramér–Rao bound of the
flange position for the trial's training poses.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import least_squares

from twin.analysis.uncertainty import cramer_rao_flange_rms, rms_distance
from twin.calibration.pipeline import calibrate
from twin.calibration.predict import predict
from twin.calibration.result import CalibrationResult
from twin.cli import main
from twin.compensation.check import check_compensation
from twin.compensation.joints import compensate_program, compensate_targets
from twin.compensation.targets import reachable_targets
from twin.dataset import Measurements
from twin.export.pinocchio import urdf_flange
from twin.io.capture_file import load_capture
from twin.io.identified import load_result
from twin.io.measurements import load_measurements
from twin.io.truth import load_truth_delta
from twin.robot import random_poses
from twin.scenario import load_scenario
from twin.sim import Simulation, Twin, simulate
from twin.study.trial import noise_sigma_m, true_unknowns

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"
WORKSPACE = 500


def _against_truth(sim: Simulation, result: CalibrationResult,
                   data: Measurements | None = None) -> tuple[float, float, float]:
    """Flange RMS error of the method and of the referee against the truth over workspace poses,
    and the Cramér–Rao bound of it, m (``data``: what was calibrated, the simulation's if
    None)."""
    model = result.model
    train = (sim.measurements if data is None else data).subset(result.train_rows)
    x_true = true_unknowns(sim, model)
    sigma_m = noise_sigma_m(sim, model.jacobian(x_true, train)[1])
    workspace = random_poses(sim.robot, WORKSPACE, np.random.default_rng(1))
    lower, upper = model.bounds()
    referee = least_squares(lambda x: model.residuals(x, train), np.zeros(model.n_params),
                            jac=lambda x: model.jacobian(x, train)[1], bounds=(lower, upper),
                            method="trf", x_scale="jac")
    at = model.poses(workspace)
    truth = sim.true_robot.flange_positions(workspace)
    return (rms_distance(model.flange_positions(result.solver.x, at), truth),
            rms_distance(model.flange_positions(referee.x, at), truth),
            cramer_rao_flange_rms(model, x_true, train, sigma_m, workspace))


@pytest.mark.slow
def test_ur5e_from_its_urdf_calibrates_to_the_bound_and_goes_back_into_it(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`twin simulate` a UR5e read from its URDF (Hayati joints 2 and 3), `twin calibrate` the
    capture: the flange error against the truth is within 2× the Cramér–Rao bound, as the
    referee's; `twin export --format urdf` keeps every name of the source and Pinocchio's FK of
    it is the result's model (to the result file's 1e-6 mm / 1e-6° rounding)."""
    out = tmp_path / "capture"
    assert main(["simulate", str(SCENARIOS / "geometric_ur5e.toml"), "--out", str(out)]) == 0
    assert (out / "robot.urdf").read_text() == (ROOT / "models/ur5e/ur5e.urdf").read_text()
    assert main(["calibrate", str(out / "capture.toml"), "--json",
                 str(tmp_path / "result.json")]) == 0
    printed = capsys.readouterr().out
    assert "δd|beta [mm|deg]" in printed and "Identified dh/hayati errors" in printed
    capture = load_capture(out / "capture.toml")
    robot = capture.robot
    assert robot.structure.parametrisation == ("dh", "hayati", "hayati", "dh", "dh", "dh")
    # The capture's own data, calibrated as the CLI did; the twin's truth from the same seed.
    sim = simulate(load_scenario(SCENARIOS / "geometric_ur5e.toml"))
    data = load_measurements(capture.measurements, robot)
    assert len(data) == len(sim.measurements)
    result = calibrate(robot, data, capture.port_m, method="lm", seed=0)
    flange_m, referee_m, bound_m = _against_truth(sim, result, data)
    print(f"UR5e: flange {flange_m * 1e3:.4f} mm, referee {referee_m * 1e3:.4f} mm, "
          f"bound {bound_m * 1e3:.4f} mm")
    assert flange_m <= 2.0 * bound_m and referee_m <= 2.0 * bound_m
    document = json.loads((tmp_path / "result.json").read_text())
    assert document["robot"]["name"] == "ur5e"
    identified = load_result(tmp_path / "result.json", robot)
    assert main(["export", str(tmp_path / "result.json"), "--robot", str(out / "robot.toml"),
                 "--format", "urdf", "--out", str(tmp_path / "calibrated.urdf")]) == 0
    text = (tmp_path / "calibrated.urdf").read_text()
    import pinocchio as pin

    names = [frame.name for frame in pin.buildModelFromXML(text).frames]
    assert names == [frame.name for frame in
                     pin.buildModelFromUrdf(str(ROOT / "models/ur5e/ur5e.urdf")).frames]
    q = random_poses(robot, 300, np.random.default_rng(2))
    found = urdf_flange(text, robot.joint_names, q, "tool0", "world")
    expected = identified.model.flange_positions(identified.x, identified.model.poses(q))
    np.testing.assert_allclose(found[:, :3, 3], expected, rtol=0.0, atol=1e-7)


@pytest.mark.parametrize("name", ["fr3", "scara4"])
def test_seven_and_four_axes_end_to_end(name: str) -> None:
    """A 7-axis (FR3, from its URDF) and a 4-axis chain: simulate, calibrate (within 2× the
    bound, like the referee), predict the flange at new poses (the model against the twin's
    true flange), compensate Cartesian targets and a program in the twin: the true flange error
    falls from millimetres to micrometres; the 4-axis program is compensated for position."""
    scenario = load_scenario(SCENARIOS / f"geometric_{name}.toml")
    sim = simulate(scenario)
    robot = sim.robot
    assert robot.n_joints == {"fr3": 7, "scara4": 4}[name]
    result = calibrate(robot, sim.measurements, sim.port_nominal_m, method="lm", seed=0)
    flange_m, referee_m, bound_m = _against_truth(sim, result)
    print(f"{name}: flange {flange_m * 1e3:.4f} mm, referee {referee_m * 1e3:.4f} mm, "
          f"bound {bound_m * 1e3:.4f} mm")
    assert flange_m <= 2.0 * bound_m and referee_m <= 2.0 * bound_m
    # Predict: where the identified model puts the flange at poses it never saw.
    twin = Twin.build(sim.true_robot, sim.port_m)
    rng = np.random.default_rng(3)
    q_new, target_m = reachable_targets(robot, 200, rng)
    predicted = predict(result, q_new).position_m
    true_at_new = twin.flange_positions(q_new)
    assert rms_distance(predicted, true_at_new) < 0.05 * rms_distance(
        robot.flange_positions(q_new), true_at_new)
    # Compensate Cartesian targets, moving the true robot in the twin.
    solved = compensate_targets(result.identified_geometry, target_m, q_new)
    check = check_compensation(target_m, true_at_new, twin.flange_positions(solved.q_rad), solved)
    assert check.n_failed <= 10
    assert check.compensated.rmse < 0.05 * check.nominal.rmse and check.compensated.rmse < 5e-5
    # Compensate a program: full pose on 7 joints, position on 4.
    program = compensate_program(robot, result.identified_geometry, q_new)
    assert np.mean(program.ok) > 0.95
    reached = twin.flange_positions(program.q_rad[program.ok])
    assert rms_distance(reached, target_m[program.ok]) < 5e-5
    if robot.n_joints >= 6:
        assert np.all(program.rotation_error_rad[program.converged] <= 1e-10)
    else:
        assert np.max(program.rotation_error_rad) > 0  # reported, not solved


@pytest.mark.parametrize("name", ["fr3", "scara4"])
def test_seven_and_four_axes_through_the_commands(name: str, tmp_path: Path) -> None:
    """The same arms through the command line: twin simulate, twin calibrate --json, twin
    predict on new poses (q1..qN) — within 2× the bound's scale of the twin's true flange — and
    twin compensate --joints on them."""
    sim_dir, result = tmp_path / "sim", tmp_path / "result.json"
    assert main(["simulate", str(SCENARIOS / f"geometric_{name}.toml"), "--out",
                 str(sim_dir)]) == 0
    assert main(["calibrate", str(sim_dir / "capture.toml"), "--json", str(result)]) == 0
    capture = load_capture(sim_dir / "capture.toml")
    robot = capture.robot
    q_new, _ = reachable_targets(robot, 50, np.random.default_rng(4))
    columns = [f"q{i + 1}" for i in range(robot.n_joints)]
    poses = tmp_path / "poses.csv"
    poses.write_text(",".join(columns) + "\n" + "".join(
        ",".join(repr(float(v)) for v in np.rad2deg(row)) + "\n" for row in q_new))
    robot_file = sim_dir / "robot.toml"
    predicted_csv = tmp_path / "predicted.csv"
    assert main(["predict", "--identified", str(result), "--joints", str(poses), "--robot",
                 str(robot_file), "--out", str(predicted_csv)]) == 0
    lines = predicted_csv.read_text().splitlines()
    header = lines[0].split(",")
    xyz = np.array([[float(v) for v in line.split(",")[header.index("x"):
                                                          header.index("x") + 3]]
                    for line in lines[1:]]) * 1e-3
    true_robot = robot.perturbed(load_truth_delta(sim_dir / "truth.json", robot.n_joints,
                                                  robot.is_length))
    true_at_new = Twin.build(true_robot, capture.port_m).flange_positions(q_new)
    assert rms_distance(xyz, true_at_new) < 0.05 * rms_distance(
        robot.flange_positions(q_new), true_at_new)
    corrected = tmp_path / "corrected.csv"
    assert main(["compensate", "--identified", str(result), "--joints", str(poses), "--robot",
                 str(robot_file), "--out", str(corrected)]) == 0
    rows = corrected.read_text().splitlines()
    assert rows[0].split(",")[:robot.n_joints] == columns and len(rows) == len(q_new) + 1
