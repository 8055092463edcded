"""Joint-level errors end to end: recovery against the truth (the core's own model, with scipy as
referee; the MuJoCo twin's physical flange), the calibrate, predict and plan commands."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import least_squares

from twin.analysis.uncertainty import cramer_rao_flange_rms, rms_distance
from twin.calibration.pipeline import calibrate
from twin.calibration.predict import predict
from twin.calibration.settings import CalibrationSettings
from twin.calibration.setup import make_model
from twin.cli import main
from twin.dataset import Measurements, approach_directions
from twin.io.identified import load_result
from twin.kinds.length import length_measurements
from twin.rig import Rig
from twin.robot import RobotModel, random_poses
from twin.units import deg_to_rad

ROOT = Path(__file__).resolve().parents[1]
EXTENDED = ("dh", "transmission", "backlash", "compliance")
SIGMA_M = 5e-6
ARCMIN = float(deg_to_rad(1.0 / 60.0))


def true_unknowns(model, rng: np.random.Generator, delta: np.ndarray) -> np.ndarray:
    """D-H errors, arc-minutes of transmission error and backlash, compliances of 2e4–1e5
    N·m/rad stiff joints."""
    x = np.zeros(model.n_params)
    x[model.slice("dh")] = delta.ravel()
    x[model.slice("transmission")] = rng.normal(scale=2 * ARCMIN, size=24)
    x[model.slice("backlash")] = rng.uniform(0.5, 1.5, 6) * ARCMIN
    x[model.slice("compliance")] = rng.uniform(1e-5, 5e-5, 6)
    return x


@pytest.fixture(scope="module")
def core_case(irb120: RobotModel, port_m: np.ndarray, true_delta: np.ndarray
              ) -> tuple[object, np.ndarray, Measurements]:
    """400 poses of the core's extended model (cable pulling with 5 N), σ = 5 µm."""
    rng = np.random.default_rng(21)
    model = make_model(irb120, Rig.cable(port_m, tension_n=5.0),
                       settings=CalibrationSettings(errors=EXTENDED))
    x_true = true_unknowns(model, rng, true_delta)
    q = random_poses(irb120, 400, rng)
    exact = model.measure(x_true, q, approach=approach_directions(q))
    noisy = length_measurements(q, exact.value("length_m") + rng.normal(0.0, SIGMA_M, len(q)),
                                approach=exact.approach)
    return model, x_true, noisy


@pytest.mark.slow
def test_extended_fit_recovers_the_flange_and_scipy_agrees(
    irb120: RobotModel, core_case: tuple[object, np.ndarray, Measurements]
) -> None:
    """LM on D-H + transmission + backlash + compliance reaches the noise floor (validation
    residuals as small as the truth's own), predicts the true flange within 3× its Cramér–Rao
    bound, and ends at the cost scipy's TRF (same residual, same bounds) reaches over the
    directions the answer leaves free (what the data cannot see, or cannot tell from zero,
    is held at the nominal): the same flange to a fraction of the bound. (The bench compares
    with a finite-difference TRF.)"""
    model, x_true, data = core_case
    rig = model.rig
    result = calibrate(irb120, data, rig=rig, seed=1, settings=CalibrationSettings(errors=EXTENDED))
    train = data.subset(result.train_rows)
    validation = data.subset(result.validation_rows)
    floor = float(np.sqrt(np.mean(model.residuals(x_true, validation) ** 2)))
    assert result.metrics["validation"].rmse < 1.15 * floor
    q_ws = random_poses(irb120, 300, np.random.default_rng(2))
    at_ws = model.poses(q_ws)
    truth = model.flange_positions(x_true, at_ws)
    error_m = rms_distance(result.model.flange_positions(result.x, at_ws), truth)
    bound_m = cramer_rao_flange_rms(model, x_true, train, SIGMA_M, q_ws)
    assert 0.0 < error_m < 3.0 * bound_m, (error_m, bound_m)
    assert result.unseen is not None
    free = result.unseen.seen_x  # x = free @ z: the nominal (x0 = 0) along the held directions
    referee = least_squares(lambda z: model.residuals(free @ z, train),
                            np.zeros(free.shape[1]),
                            jac=lambda z: model.jacobian(free @ z, train)[1] @ free,
                            method="trf", x_scale="jac", xtol=1e-15, ftol=1e-15, gtol=1e-15,
                            max_nfev=200)
    lower, upper = model.bounds()
    assert np.all((free @ referee.x >= lower) & (free @ referee.x <= upper))
    cost = float(np.sum(model.residuals(result.x, train) ** 2))
    assert cost == pytest.approx(2 * referee.cost, rel=1e-4)
    apart = rms_distance(model.flange_positions(free @ referee.x, at_ws),
                         model.flange_positions(result.x, at_ws))
    assert apart < 0.1 * bound_m


@pytest.mark.slow
@pytest.mark.parametrize("method", ["ekf", "amlm", "amlm-bipso"])
def test_the_papers_methods_run_on_the_extended_problem(
    irb120: RobotModel, core_case: tuple[object, np.ndarray, Measurements], method: str
) -> None:
    """EKF, AMLM and M9 fit the 60 unknowns with their own stopping rules and predict the true
    flange within 3× the Cramér–Rao bound, as LM does."""
    model, x_true, data = core_case
    result = calibrate(irb120, data, rig=model.rig, seed=1, method=method,
                       settings=CalibrationSettings(errors=EXTENDED))
    train = data.subset(result.train_rows)
    q_ws = random_poses(irb120, 300, np.random.default_rng(2))
    at_ws = model.poses(q_ws)
    error_m = rms_distance(result.model.flange_positions(result.x, at_ws),
                           model.flange_positions(x_true, at_ws))
    assert error_m < 3.0 * cramer_rao_flange_rms(model, x_true, train, SIGMA_M, q_ws)


def test_dh_alone_cannot_hold_joint_errors(
    irb120: RobotModel, core_case: tuple[object, np.ndarray, Measurements]
) -> None:
    """The same data fitted with the D-H table alone stays far above the noise: the
    joint-level errors are real signal the extended model explains."""
    model, _, data = core_case
    alone = calibrate(irb120, data, rig=model.rig, seed=1)
    assert alone.metrics["validation"].rmse > 20 * SIGMA_M


def test_predict_is_the_model_and_needs_approach(
    irb120: RobotModel, core_case: tuple[object, np.ndarray, Measurements], port_m: np.ndarray
) -> None:
    """twin.calibration.predict gives the model's measured point and length at the poses and
    approach directions given; a model with backlash refuses poses without directions; a named port
    gives the straight distance from it."""
    model, x_true, data = core_case

    class Truth:
        pass

    truth = Truth()
    truth.model, truth.x = model, x_true  # type: ignore[attr-defined]
    rows = data.subset(np.arange(30))
    prediction = predict(truth, rows.q_rad, approach=rows.approach)  # type: ignore[arg-type]
    np.testing.assert_allclose(prediction.position_m, model.positions(x_true, rows), atol=1e-15)
    assert "length_m" in prediction.readings
    np.testing.assert_allclose(prediction.readings["length_m"],
                               model.measure(x_true, rows.q_rad, approach=rows.approach)
                               .value("length_m"),
                               atol=1e-15)
    from twin.errors import InputError

    with pytest.raises(InputError, match=r"approach1\.\.approach6"):
        predict(truth, rows.q_rad)  # type: ignore[arg-type]
    elsewhere = predict(truth, rows.q_rad, approach=rows.approach,  # type: ignore[arg-type]
                        port_m=[0.1, 0.5, 0.0])
    assert "length_m" in elsewhere.readings
    np.testing.assert_allclose(elsewhere.readings["length_m"], np.linalg.norm(
        elsewhere.position_m - [0.1, 0.5, 0.0], axis=1), atol=1e-15)


def scenario_with_joint_errors(tmp_path: Path, *, poses: int = 250) -> Path:
    """The paper's rig (transmission error, backlash, compliant servos, 5 N cable) with the
    masses 20 % off and every joint-level group fitted."""
    text = (ROOT / "scenarios" / "paper_irb120.toml").read_text(encoding="utf-8")
    robot = (ROOT / "models" / "irb120.toml").as_posix()
    text = text.replace('robot = "../models/irb120.toml"', f'robot = "{robot}"')
    text = text.replace("count = 120", f"count = {poses}")
    text = text.replace("tension_n = 5.0", "tension_n = 5.0\nmass_error = 0.2")
    text = text.replace('stop = "paper"', f"errors = {json.dumps(list(EXTENDED))}")
    path = tmp_path / "joint_errors.toml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def capture(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """`twin simulate` of the joint-error scenario, then `twin calibrate --json`."""
    folder = tmp_path_factory.mktemp("joint_errors")
    scenario = scenario_with_joint_errors(folder)
    assert main(["simulate", str(scenario), "--out", str(folder / "run")]) == 0
    assert main(["calibrate", str(folder / "run" / "capture.toml"), "--json",
                 str(folder / "run" / "result.json")]) == 0
    return folder / "run"


@pytest.mark.slow
def test_simulated_capture_records_what_the_calibration_needs(capture: Path) -> None:
    """The capture asks for the extended groups and the cable's tension; the measurements carry
    approach1..6; the truth names the joint-level errors in the calibration's terms."""
    text = (capture / "capture.toml").read_text()
    assert 'errors = ["dh", "transmission", "backlash", "compliance"]' in text
    assert "cable_tension_n = 5.0" in text
    assert (capture / "measurements.csv").read_text().splitlines()[0].endswith(
        ",length,approach1,approach2,approach3,approach4,approach5,approach6")
    truth = json.loads((capture / "truth.json").read_text())
    assert truth["joint_unknowns"]["backlash"] == pytest.approx([0.025] * 3 + [0.0125] * 3)
    assert truth["physics"]["mass_error"] == 0.2
    result = json.loads((capture / "result.json").read_text())
    assert result["unknowns"]["groups"] == [*EXTENDED]
    assert result["unknowns"]["rig"]["tension_n"] == 5.0


@pytest.mark.slow
def test_predict_reproduces_the_twins_flange(capture: Path, tmp_path: Path) -> None:
    """`twin predict` on the capture's poses puts the flange where the twin's physical flange
    was (MuJoCo at rest: transmission error, backlash for each pose's approach, sag under the
    true masses and the cable) within 3× the result's predicted accuracy; a D-H-only result is
    some ten times further off."""
    from twin.io.measurements import load_measurements
    from twin.io.robot_file import load_robot
    from twin.scenario import load_scenario
    from twin.sim import Twin, simulate

    scenario = load_scenario(scenario_with_joint_errors(tmp_path))
    sim = simulate(scenario)
    robot = load_robot(capture / "robot.toml")
    data = load_measurements(capture / "measurements.csv", robot)
    twin = Twin.build(sim.true_robot, sim.port_m, scenario.physics, sim.joint_errors)
    truth_mm = 1e3 * twin.at_rest(data.q_rad, data.approach).flange_m
    out = tmp_path / "pred.csv"
    argv = ["predict", "--identified", str(capture / "result.json"), "--joints",
            str(capture / "measurements.csv"), "--robot", str(capture / "robot.toml")]
    assert main([*argv, "--out", str(out)]) == 0
    table = np.genfromtxt(out, delimiter=",", names=True)
    predicted_mm = np.stack([table["x"], table["y"], table["z"]], axis=1)
    result = json.loads((capture / "result.json").read_text())
    error_mm = rms_distance(predicted_mm, truth_mm)
    assert error_mm < 3 * result["predicted_flange_rms"], (error_mm, result)
    lengths = np.genfromtxt(capture / "measurements.csv", delimiter=",", names=True)["length"]
    assert np.sqrt(np.mean((table["length"] - lengths) ** 2)) < 0.02
    dh_only = tmp_path / "dh.json"
    assert main(["calibrate", str(capture / "capture.toml"), "--errors", "dh", "--json",
                 str(dh_only)]) == 0
    assert main([*argv[:2], str(dh_only), *argv[3:], "--out", str(out)]) == 0
    table = np.genfromtxt(out, delimiter=",", names=True)
    far_mm = rms_distance(np.stack([table["x"], table["y"], table["z"]], axis=1), truth_mm)
    assert far_mm > 10 * error_mm


def test_load_result_rebuilds_the_extended_model(capture: Path) -> None:
    """A result read back predicts what the calibration's own model predicts."""
    from twin.io.robot_file import load_robot

    robot = load_robot(capture / "robot.toml")
    identified = load_result(capture / "result.json", robot)
    assert identified.model.rig.tension_n == 5.0 and identified.model.needs_approach
    q = random_poses(robot, 5, np.random.default_rng(0))
    first = predict(identified, q, approach=approach_directions(q))
    assert np.all(np.isfinite(first.position_m))


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["calibrate", "{csv}", "--port", "600,-400,100", "--errors", "dh,backlash"],
         "found no columns approach1..approach6, expected approach1..approach6"),
        (["calibrate", "{csv}", "--port", "600,-400,100", "--errors", "dh,gears"],
         "--errors: found 'dh,gears', expected dh,transmission,backlash,compliance"),
        (["calibrate", "{csv}", "--port", "600,-400,100", "--cable-tension", "-1"],
         "--cable-tension: found '-1', expected a number in [0, 1000]"),
        (["calibrate", "{csv}", "--port", "600,-400,100", "--errors", "auto", "--method", "all"],
         "--errors: found --errors auto with --method all"),
        (["predict", "--identified", "{result}", "--joints", "{poses}", "--robot", "{robot}",
          "--out", "{tmp}/p.csv"], "poses.csv: found no columns approach1..approach6"),
    ],
)
def test_user_mistakes(argv: list[str], message: str, csv_path: Path, capture: Path,
                       tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """One line on stderr, exit code 2, nothing written."""
    poses = tmp_path / "poses.csv"
    poses.write_text("q1,q2,q3,q4,q5,q6\n10,20,30,40,50,60\n")
    paths = {"csv": str(csv_path), "result": str(capture / "result.json"), "poses": str(poses),
             "robot": str(capture / "robot.toml"), "tmp": str(tmp_path)}
    assert main([arg.format(**paths) for arg in argv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("twin: error: ") and message in err, err
    assert not (tmp_path / "p.csv").exists()


@pytest.mark.slow
def test_errors_auto_chooses_and_reports(capture: Path, tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    """--errors auto fits the nested models on the same split, prints the table and writes the
    chosen one (the lowest BIC) with the comparison; on the twin's data each group lowers the
    BIC and the choice has every kind of joint-level error."""
    out = tmp_path / "auto.json"
    assert main(["calibrate", str(capture / "capture.toml"), "--errors", "auto", "--json",
                 str(out)]) == 0
    printed = capsys.readouterr().out
    assert "dh+compliance+backlash+transmission" in printed and "<- chosen" in printed
    document = json.loads(out.read_text())
    candidates = document["error_choice"]["candidates"]
    assert [c["errors"] for c in candidates] == [
        ["dh"], ["dh", "compliance"], ["dh", "compliance", "backlash"],
        ["dh", "compliance", "backlash", "transmission"],
        ["dh", "link_compliance", "backlash", "transmission"]]
    chosen = [c for c in candidates if c["chosen"]]
    assert len(chosen) == 1 and chosen[0]["bic"] == min(c["bic"] for c in candidates)
    assert chosen[0]["errors"][-1] == "transmission"  # every group the twin has
    assert [c["bic"] for c in candidates[:4]] == sorted((c["bic"] for c in candidates[:4]),
                                                        reverse=True)


def test_compensation_solves_on_the_whole_model(
    irb120: RobotModel, core_case: tuple[object, np.ndarray, Measurements]
) -> None:
    """Commands solved on the extended model put its flange (joint errors applied for the side
    each joint comes from) on the targets to 1e-9 m. Visiting the rows in order, that side is
    the move's from the row before, except where a joint moves less than its backlash: no side
    is then consistent, and the row is flagged for an approach move from the side stated. Solved
    on the identified table alone, the commands miss by the joint-level errors."""
    from twin.compensation.joints import compensate_targets, solve_in_order
    from twin.compensation.targets import reachable_targets

    model, x_true, _ = core_case
    q, targets = reachable_targets(irb120, 60, np.random.default_rng(4))
    ordered = solve_in_order(model, x_true, lambda arm, joints: compensate_targets(
        arm, targets, q, joints), q)
    solved = ordered.solved
    assert np.all(solved.ok) and ordered.approach is not None
    reached = model.flange_positions(x_true, model.poses(solved.q_rad,
                                                         approach=ordered.approach))
    assert np.max(np.linalg.norm(reached - targets, axis=1)) < 1e-9
    straight = np.all(approach_directions(solved.q_rad) == ordered.approach, axis=1)
    np.testing.assert_array_equal(~straight, ordered.approach_moves)
    assert 0 < np.sum(ordered.approach_moves) < 5  # this seed: joint 3 moves 0.04° at row 35
    table = irb120.perturbed(model.table(x_true) - irb120.dh)
    table_only = compensate_targets(table, targets, q)
    missed = model.flange_positions(x_true, model.poses(table_only.q_rad))
    assert rms_distance(missed, targets) > 1e-4


@pytest.mark.slow
def test_compensation_puts_the_twins_robot_on_its_targets(tmp_path: Path) -> None:
    """In the twin (paper rig, masses 20 % off): commands compensated with the extended model
    bring the true robot (MuJoCo at rest, joint errors and sag) to within 3× the calibration's
    predicted flange accuracy of its targets; with the D-H table alone it stays tenths of a
    millimetre off."""
    from twin.calibration.pipeline import calibrate
    from twin.compensation.joints import compensate_targets, solve_in_order
    from twin.compensation.targets import reachable_targets
    from twin.scenario import load_scenario
    from twin.sim import Twin, simulate

    scenario = load_scenario(scenario_with_joint_errors(tmp_path, poses=300))
    sim = simulate(scenario)
    rig = Rig.cable(sim.port_nominal_m, tension_n=scenario.physics.tension_n)
    result = calibrate(sim.robot, sim.measurements, rig=rig, seed=3,
                       settings=CalibrationSettings(errors=scenario.calibration.errors))
    twin = Twin.build(sim.true_robot, sim.port_m, scenario.physics, sim.joint_errors)
    q, targets = reachable_targets(sim.robot, 200, np.random.default_rng(5))
    ordered = solve_in_order(result.model, result.x, lambda arm, joints: compensate_targets(
        arm, targets, q, joints), q)
    solved = ordered.solved
    assert np.all(solved.ok)
    reached = twin.flange_positions(solved.q_rad, ordered.approach)
    assert result.uncertainty is not None
    error_m = rms_distance(reached, targets)
    assert error_m < 3 * result.uncertainty.flange_rms_m, (error_m, result.uncertainty)
    plain = compensate_targets(result.identified_geometry, targets, q)
    assert rms_distance(twin.flange_positions(plain.q_rad, approach_directions(plain.q_rad)),
                        targets) > 30 * error_m


def test_compensate_cli_uses_the_whole_model(capture: Path, tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    """`twin compensate --joints` with an extended result corrects by more than the table
    alone would; the cable unhooked (--cable-tension 0) changes the correction; a program's
    approach columns are used as given."""
    from twin.compensation.targets import reachable_targets
    from twin.io.robot_file import load_robot

    robot = load_robot(capture / "robot.toml")
    q_deg = np.rad2deg(reachable_targets(robot, 60, np.random.default_rng(6))[0])
    # Away from the elbow's stretched-arm singularity (q3 = −77°) and the wrist's (q5 = 0):
    # within 15° of them a sub-degree change of the identified wrist moves a nominal pose
    # past what the real arm reaches, and `unreachable` would be the right answer there.
    q_deg = q_deg[(np.abs(q_deg[:, 2] + 77.0) > 15.0) & (np.abs(q_deg[:, 4]) > 15.0)][:20]
    program = tmp_path / "program.csv"
    program.write_text("q1,q2,q3,q4,q5,q6\n" + "\n".join(",".join(f"{v:.4f}" for v in row)
                                                        for row in q_deg) + "\n")
    base = ["compensate", "--identified", str(capture / "result.json"), "--robot",
            str(capture / "robot.toml"), "--joints"]
    outputs = {}
    for label, extra in (("hooked", []), ("unhooked", ["--cable-tension", "0"])):
        out = tmp_path / f"{label}.csv"
        assert main([*base, str(program), "--out", str(out), *extra]) == 0
        table = np.genfromtxt(out, delimiter=",", names=True, dtype=None, encoding="utf-8")
        assert set(table["status"]) == {"ok"} and "approach6" in table.dtype.names
        outputs[label] = np.stack([table[f"q{i}"] for i in range(1, 7)], axis=1)
    assert "20 rows: 20 ok" in capsys.readouterr().out
    apart = np.abs(outputs["hooked"] - outputs["unhooked"])
    assert 1e-6 < np.max(apart) < 0.01  # degrees: the cable's 5 N on ~1e-5 rad/(N·m)
    signs = np.where(np.arange(20) % 2, 1, -1)[:, None] * np.ones((1, 6), dtype=int)
    given = tmp_path / "given.csv"
    given.write_text(program.read_text().splitlines()[0] + ","
                     + ",".join(f"approach{i}" for i in range(1, 7)) + "\n" + "\n".join(
                         line + "," + ",".join(f"{s:+d}" for s in row) for line, row in
                         zip(program.read_text().splitlines()[1:], signs, strict=True)) + "\n")
    assert main([*base, str(given), "--out", str(tmp_path / "given_out.csv")]) == 0
    table = np.genfromtxt(tmp_path / "given_out.csv", delimiter=",", names=True, dtype=None,
                          encoding="utf-8")
    assert not np.allclose(np.stack([table[f"q{i}"] for i in range(1, 7)], axis=1),
                           outputs["hooked"], atol=1e-4)


def test_plan_designs_for_the_chosen_groups(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    """`twin plan --errors` plans for the extended model's base parameters, and its plan
    predicts a smaller flange error than as many random poses; a group it does not know is one
    line naming the choices."""
    out = tmp_path / "plan.csv"
    argv = ["plan", "--port", "600,-400,100", "--poses", "80", "--candidates", "400",
            "--joint-limits-only", "--cable-tension", "5", "--out", str(out)]
    assert main([*argv, "--errors", "dh,transmission,backlash,compliance"]) == 0
    printed = capsys.readouterr().out
    assert "49 base parameters of 60 unknowns" in printed
    rows = {line.split()[0]: float(line.split()[-1]) for line in printed.splitlines()
            if line.strip().startswith(("planned", "random"))}
    assert rows["planned"] < rows["random"]
    assert len(out.read_text().splitlines()) == 81
    assert main([*argv, "--errors", "auto"]) == 2
    assert "--errors: found 'auto', expected dh,transmission" in capsys.readouterr().err


def test_identify_names_what_the_extended_model_cannot_see(
        capture: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`twin identify --errors` on the twin's capture: rank 49 of 60, every joint-6 term among
    the unidentifiable directions beside the D-H ones, σ of the joint-level errors printed."""
    assert main(["identify", str(capture / "capture.toml"), "--errors",
                 "dh,transmission,backlash,compliance"]) == 0
    printed = capsys.readouterr().out
    assert "rank 49 of 60" in printed
    unseen = next(line for line in printed.splitlines() if "not identifiable" in line)
    for name in ("sin_q6", "cos_q6", "sin2_q6", "cos2_q6", "backlash6", "compliance6",
                 "theta6", "d2-d3"):
        assert name in unseen
    assert "Identified joint-level errors" in printed


@pytest.mark.slow
def test_link_compliance_holds_masses_off_link_by_link(tmp_path: Path) -> None:
    """Soft servos (the compliance regime) with the masses 20 % off link by link: compliance
    split by link predicts the twin's physical flange within 3× its predicted accuracy, closer
    than one compliance per joint, which cannot follow how the torque's shape changed."""
    from twin.scenario import load_scenario
    from twin.sim import Twin, simulate

    text = (ROOT / "scenarios" / "compliance_irb120.toml").read_text(encoding="utf-8")
    robot = (ROOT / "models" / "irb120.toml").as_posix()
    text = text.replace('robot = "../models/irb120.toml"', f'robot = "{robot}"')
    text = text.replace("count = 120", "count = 300")
    text = text.replace("tension_n = 5.0", "tension_n = 5.0\nmass_error = 0.2")
    path = tmp_path / "soft.toml"
    path.write_text(text, encoding="utf-8")
    scenario = load_scenario(path)
    sim = simulate(scenario, seed=1)
    rig = Rig.cable(sim.port_nominal_m, tension_n=scenario.physics.tension_n)
    q_ws = random_poses(sim.robot, 300, np.random.default_rng(8))
    twin = Twin.build(sim.true_robot, sim.port_m, scenario.physics, sim.joint_errors)
    truth = twin.at_rest(q_ws, approach_directions(q_ws)).flange_m
    errors = {}
    for compliant in ("compliance", "link_compliance"):
        result = calibrate(sim.robot, sim.measurements, rig=rig, seed=1,
                           settings=CalibrationSettings(errors=("dh", "transmission", "backlash",
                                                                compliant)))
        predicted = result.model.flange_positions(result.x, result.model.poses(q_ws))
        assert result.uncertainty is not None
        errors[compliant] = (rms_distance(predicted, truth), result.uncertainty.flange_rms_m)
    error_m, accuracy_m = errors["link_compliance"]
    assert error_m < 3 * accuracy_m, errors
    assert error_m < errors["compliance"][0], errors


def test_export_says_what_a_robot_file_cannot_hold(capture: Path, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    """Exporting an extended result writes the identified table and warns that the joint-level
    errors are not in the file."""
    out = tmp_path / "identified.toml"
    assert main(["export", str(capture / "result.json"), "--robot", str(capture / "robot.toml"),
                 "--format", "dh", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "joint-level errors (transmission, backlash, compliance)" in err and out.exists()
