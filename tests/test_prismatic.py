"""Prismatic joints end to end: the FR3 on a torso lift, given only as its URDF, runs through
simulate → calibrate → predict → compensate → export in the MuJoCo twin, and a 9-joint chain (a
two-axis gantry carrying the FR3) loads, calibrates and compensates in the core.

The referee of every number is the twin's truth and, for the calibration, scipy's
``least_squares`` on the same residual, run here; the bound is the Cramér–Rao bound of the
flange position for the trial's training poses. A prismatic joint's q is in m inside and in mm
in every file.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import least_squares

from twin.analysis.uncertainty import cramer_rao_flange_rms, rms_distance
from twin.calibration.pipeline import calibrate
from twin.cli import main
from twin.compensation.joints import compensate_program
from twin.compensation.targets import reachable_targets
from twin.export.pinocchio import urdf_flange
from twin.geometry.kinematics import fixed_transforms, rigid_transform
from twin.geometry.parametrisation import convert
from twin.io.capture_file import load_capture
from twin.io.identified import load_result
from twin.io.measurements import load_measurements
from twin.io.robot_file import load_robot, robot_to_toml
from twin.kinds.length import length_measurements
from twin.rig import Rig
from twin.robot import RobotModel, random_poses
from twin.scenario import load_scenario
from twin.sim import Twin, simulate
from twin.study.trial import noise_sigma_m, true_unknowns
from twin.synthetic import synthesize

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "geometric_torso.toml"
WORKSPACE = 500


def _joint_file(path: Path, robot: RobotModel, q_rad: np.ndarray) -> None:
    """A pose CSV as a person writes it: q1..qN in degrees, a prismatic joint's in mm."""
    values = np.where(robot.prismatic, q_rad * 1e3, np.rad2deg(q_rad))
    path.write_text(",".join(f"q{i + 1}" for i in range(robot.n_joints)) + "\n" + "".join(
        ",".join(repr(float(v)) for v in row) + "\n" for row in values))


PIN_WEIGHT = 1e2
"""m of residual per unit of a held direction (bound-scaled): a millionth of the box there
costs ten times a reading's noise."""


@pytest.mark.slow
def test_torso_from_its_urdf_calibrates_to_the_bound(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """`twin simulate` the FR3 on its lift (8 joints, the lift a prismatic Hayati joint, two
    stations), `twin calibrate` the capture: the flange error over held-out workspace poses is
    within 2× the Cramér–Rao bound, as the referee's (scipy's least_squares on the same
    residual, over the directions the answer leaves free), and the two answers' flanges agree
    far inside the bound."""
    out = tmp_path / "capture"
    assert main(["simulate", str(SCENARIO), "--out", str(out)]) == 0
    assert (out / "robot.urdf").read_text() == (ROOT / "models/fr3_torso/fr3_torso.urdf"
                                                ).read_text()
    header = (out / "measurements.csv").read_text().splitlines()[1].split(",")
    assert 0.0 <= float(header[0]) <= 400.0  # the lift's travel, in mm
    assert main(["calibrate", str(out / "capture.toml"), "--json",
                 str(tmp_path / "result.json")]) == 0
    assert "fr3_torso" in capsys.readouterr().out
    capture = load_capture(out / "capture.toml")
    robot = capture.robot
    assert robot.structure.joint_types[0] == "prismatic" and robot.n_joints == 8
    sim = simulate(load_scenario(SCENARIO))
    data = load_measurements(capture.measurements, robot)
    np.testing.assert_allclose(data.q_rad, sim.measurements.q_rad, rtol=0, atol=1e-12)
    result = calibrate(robot, data, rig=capture.rig, method="lm", seed=0)
    model = result.model
    train = data.subset(result.train_rows)
    x_true = true_unknowns(sim, model)
    sigma_m = noise_sigma_m(sim, model.jacobian(x_true, train)[1])
    # The referee fits the same residual in the same box with the answer's held directions
    # (what the data cannot see, or cannot tell from zero) pinned at the nominal by stiff rows.
    assert result.unseen is not None
    pin = PIN_WEIGHT * result.unseen.basis.T / result.unseen.scale  # (k, p)
    lower, upper = model.bounds()
    referee = least_squares(
        lambda x: np.concatenate([model.residuals(x, train), pin @ x]), np.zeros(model.n_params),
        jac=lambda x: np.vstack([model.jacobian(x, train)[1], pin]), bounds=(lower, upper),
        method="trf", x_scale="jac")
    workspace = random_poses(robot, WORKSPACE, np.random.default_rng(1))
    at = model.poses(workspace)
    truth = sim.true_robot.flange_positions(workspace)
    ours = model.flange_positions(result.solver.x, at)
    theirs = model.flange_positions(referee.x, at)
    bound_m = cramer_rao_flange_rms(model, x_true, train, sigma_m, workspace)
    flange_m, referee_m = rms_distance(ours, truth), rms_distance(theirs, truth)
    print(f"torso: flange {flange_m * 1e3:.4f} mm, referee {referee_m * 1e3:.4f} mm, bound "
          f"{bound_m * 1e3:.4f} mm, apart {rms_distance(ours, theirs) * 1e3:.5f} mm")
    assert flange_m <= 2.0 * bound_m and referee_m <= 2.0 * bound_m
    assert rms_distance(ours, theirs) <= 0.25 * bound_m
    assert rms_distance(robot.flange_positions(workspace), truth) > 20.0 * bound_m


@pytest.mark.slow
def test_torso_result_alone_predicts_compensates_and_exports(tmp_path: Path) -> None:
    """The torso's result file alone (no --robot): `twin predict` puts the flange at new poses
    (q1 in mm) near the twin's true flange, `twin compensate --joints` corrects them (the
    lift's correction in mm, the true flange error falling twentyfold in the twin), and
    `twin export --format urdf` writes the robot's own URDF whose Pinocchio FK is the result's
    model to 1e-9 m."""
    out, result = tmp_path / "capture", tmp_path / "result.json"
    assert main(["simulate", str(SCENARIO), "--out", str(out)]) == 0
    assert main(["calibrate", str(out / "capture.toml"), "--json", str(result)]) == 0
    identified = load_result(result)
    robot = identified.robot
    sim = simulate(load_scenario(SCENARIO))
    q_new, _ = reachable_targets(robot, 60, np.random.default_rng(4))
    poses = tmp_path / "poses.csv"
    _joint_file(poses, robot, q_new)
    predicted_csv = tmp_path / "predicted.csv"
    assert main(["predict", "--identified", str(result), "--joints", str(poses),
                 "--out", str(predicted_csv)]) == 0
    lines = predicted_csv.read_text().splitlines()
    columns = lines[0].split(",")
    xyz = np.array([[float(v) for v in line.split(",")[columns.index("x"):
                                                          columns.index("x") + 3]]
                    for line in lines[1:]]) * 1e-3
    twin = Twin.build(sim.true_robot, None)
    true_at_new = twin.flange_positions(q_new)
    nominal_error = rms_distance(robot.flange_positions(q_new), true_at_new)
    assert rms_distance(xyz, true_at_new) < 0.05 * nominal_error
    corrected = tmp_path / "corrected.csv"
    assert main(["compensate", "--identified", str(result), "--joints", str(poses),
                 "--out", str(corrected)]) == 0
    rows = [line.split(",") for line in corrected.read_text().splitlines()]
    assert rows[0][:9] == [*(f"q{i + 1}" for i in range(8)), "status"]
    ok = np.array([row[8] == "ok" for row in rows[1:]])
    assert ok.mean() > 0.95
    commands = np.array([[float(v) for v in row[:8]] for row, good in zip(rows[1:], ok,
                                                                         strict=True) if good])
    q_commands = np.where(robot.prismatic, commands * 1e-3, np.deg2rad(commands))
    lift_mm = commands[:, 0] - q_new[ok, 0] * 1e3
    assert np.max(np.abs(lift_mm)) < 10.0  # the lift's correction, mm
    reached = twin.flange_positions(q_commands)
    target = robot.flange_positions(q_new[ok])
    assert rms_distance(reached, target) < 0.05 * nominal_error
    urdf = tmp_path / "calibrated.urdf"
    assert main(["export", str(result), "--format", "urdf", "--out", str(urdf)]) == 0
    text = urdf.read_text()
    assert 'name="torso_lift_joint" type="prismatic"' in text
    q = random_poses(robot, 300, np.random.default_rng(2))
    found = urdf_flange(text, robot.joint_names, q, "fr3_link8", "base")
    expected = identified.model.flange_positions(identified.x, identified.model.poses(q))
    np.testing.assert_allclose(found[:, :3, 3], expected, rtol=0.0, atol=1e-9)


def _gantry(tmp_path: Path) -> RobotModel:
    """A 9-joint chain written as a model file and loaded: a gantry's x and y travel
    (prismatic, 1.5 m and 1 m) carrying the FR3 hanging below it."""
    fr3 = load_robot(ROOT / "models" / "fr3" / "fr3.urdf")
    arm = fixed_transforms(fr3.structure, fr3.dh)
    fixed = np.stack([
        rigid_transform([0.0, 0.0, 2.0], [0.0, np.pi / 2, 0.0]),    # x travel along base x
        rigid_transform([0.0, 0.0, 0.0], [-np.pi / 2, 0.0, 0.0]),   # y travel along base y
        rigid_transform([0.3, 0.0, 0.0], [0.0, -np.pi / 2, 0.0]) @ rigid_transform(
            [0, 0, 0], [np.pi, 0, 0]) @ arm[0],                     # the arm hangs down
        *arm[1:]])
    structure, table = convert(fixed, "auto", ("prismatic", "prismatic") + ("revolute",) * 7)
    robot = RobotModel("gantry fr3", table, np.r_[0.0, 0.0, fr3.lower_rad],
                       np.r_[1.5, 1.0, fr3.upper_rad], structure=structure)
    path = tmp_path / "gantry.toml"
    path.write_text(robot_to_toml(robot))
    return load_robot(path)


@pytest.mark.slow
def test_nine_joints_load_calibrate_and_compensate(tmp_path: Path) -> None:
    """A two-axis gantry with the FR3 (9 joints, two prismatic) from a model file: FK equal to
    the chain it was written from; cable data made by the core from a perturbed table and two
    stations calibrate to within 2× the Cramér–Rao bound of the flange; the program compensated
    on the identified model reaches the nominal flange to 1e-9 m."""
    robot = _gantry(tmp_path)
    assert robot.n_joints == 9 and robot.prismatic.tolist() == [True, True] + [False] * 7
    text = (tmp_path / "gantry.toml").read_text()
    assert text.count('type = "prismatic"') == 2 and "upper = 1500.0" in text
    rng = np.random.default_rng(9)
    scale = np.where(robot.is_length, 1e-3, np.deg2rad(0.1))
    truth = robot.perturbed(rng.uniform(-1.0, 1.0, scale.shape) * scale)
    q = random_poses(robot, 300, rng)
    ports = np.array([[1.5, -0.8, 0.0], [-0.5, 1.2, 0.0]])
    station = np.arange(len(q)) % 2
    sigma_m = 1e-5
    lengths = np.concatenate([synthesize(truth, q[station == k], ports[k], sigma_m, rng)
                              .value("length_m") for k in (0, 1)])
    order = np.concatenate([np.flatnonzero(station == k) for k in (0, 1)])
    data = length_measurements(q[order], lengths, port=station[order], port_names=("a", "b"))
    result = calibrate(robot, data, rig=Rig(ports, ("a", "b")), method="lm", seed=0)
    model = result.model
    train = data.subset(result.train_rows)
    x_true = np.zeros(model.n_params)
    x_true[model.slice("dh")] = (truth.dh - robot.dh).ravel()
    workspace = random_poses(robot, WORKSPACE, np.random.default_rng(1))
    flange_m = rms_distance(model.flange_positions(result.solver.x, model.poses(workspace)),
                            truth.flange_positions(workspace))
    bound_m = cramer_rao_flange_rms(model, x_true, train, sigma_m, workspace)
    print(f"gantry: flange {flange_m * 1e3:.4f} mm, bound {bound_m * 1e3:.4f} mm")
    assert flange_m <= 2.0 * bound_m
    q_program, _ = reachable_targets(robot, 100, np.random.default_rng(5))
    program = compensate_program(robot, result.identified_geometry, q_program)
    assert np.mean(program.ok) > 0.95
    np.testing.assert_allclose(
        result.identified_geometry.flange_transforms(program.q_rad[program.ok]),
        robot.flange_transforms(q_program[program.ok]), rtol=0.0, atol=1e-9)


def test_what_a_prismatic_joint_cannot_take_is_refused_in_one_line(tmp_path: Path) -> None:
    """RAPID holds a robot's axes in degrees: a plan module for an arm with a prismatic joint
    is refused, naming the joint; the twin's gearbox errors (angles) on a prismatic joint are
    refused, naming the key and the joint; a bound in µm/m reaches the lift's scale."""
    from dataclasses import replace

    from twin.errors import InputError
    from twin.io.rapid_plan import PlanOptions, plan_module
    from twin.io.robot_file import default_robot
    from twin.unknowns.limits import Bound

    irb120 = default_robot()
    sliding = replace(irb120, structure=replace(irb120.structure, joint_types=(
        "prismatic",) + ("revolute",) * 5))
    options = PlanOptions("v100", "tool0", "wobj0", 0.5, None)
    with pytest.raises(InputError, match="found the prismatic joint 'joint_1', expected a "
                       "robot of revolute joints for RAPID"):
        plan_module(sliding, np.zeros((2, 6)), options)
    text = SCENARIO.read_text().replace("../models", (ROOT / "models").as_posix())
    path = tmp_path / "torso.toml"
    path.write_text(text + "\n[joints]\nbacklash_arcsec = 30.0\n")
    with pytest.raises(InputError, match=r"\[joints\] backlash_arcsec: found 30 arcsec on "
                       r"joint 1, prismatic \(torso_lift_joint\), expected 0 for a prismatic"):
        load_scenario(path)
    bound = Bound.parse("scale_q=200um/m")
    assert bound.unit == "m/m" and bound.upper == pytest.approx(2e-4)
