"""Thermal growth (--errors thermal): each link's length entries grow linearly with the row's
temperature. The Jacobian against central differences, each row on its own table, a constant
temperature held at zero, recovery on the twin's warm-up against its truth within 2× the
Cramér–Rao bound and against scipy.optimize.least_squares on the same residual, and
simulate → calibrate → predict → Rerun on the command line."""

from __future__ import annotations

import csv
import json
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import least_squares

from tests.conftest import Refusals
from tests.test_viz_rerun import read_rrd, scalars
from twin.analysis.uncertainty import cramer_rao_covariance, flange_sigma, rms_distance
from twin.calibration.pipeline import calibrate
from twin.calibration.result import CalibrationResult
from twin.calibration.selection import _warming, nested_errors
from twin.calibration.settings import CalibrationSettings
from twin.calibration.setup import make_model
from twin.cli import main
from twin.dataset import TEMPERATURE, Measurements
from twin.geometry import kinematics
from twin.geometry.kinematics import point_position
from twin.io.identified import load_result
from twin.kinds.length import length_measurements
from twin.kinds.pose import pose_measurements
from twin.kinds.position import position_measurements
from twin.model import Model
from twin.rig import Rig
from twin.robot import RobotModel, random_poses
from twin.scenario import Scenario, load_scenario
from twin.sim import Simulation, simulate
from twin.sim.simulate import write_simulation
from twin.study.trial import noise_sigma_m, true_unknowns
from twin.viz import entities

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "thermal_irb120.toml"
THERMAL = CalibrationSettings(errors=("dh", "thermal"))


def _warm(data: Measurements, temperature_c: np.ndarray) -> Measurements:
    return replace(data, values={**data.values, TEMPERATURE: temperature_c})


def _model(robot: RobotModel, kind: str, errors: tuple[str, ...] = ("dh", "thermal")) -> Model:
    rig = replace(Rig.cable(np.array([0.6, -0.4, 0.1])), temperature_ref_c=23.0) \
        if kind == "length" else Rig(temperature_ref_c=23.0)
    return make_model(robot, rig, kind, CalibrationSettings(errors=errors))


@pytest.mark.slow
@pytest.mark.parametrize("kernel", ["numpy", "numba"], indirect=True)
@pytest.mark.parametrize("kind", ["length", "position", "pose"])
def test_thermal_jacobian_matches_differences(irb120: RobotModel, kind: str, kernel: str,
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    """∂r/∂x of D-H, transmission and thermal unknowns together equals central differences
    (for 6-D poses, their orientation rows too); a batch of x gives each x's residuals. On
    either kernel: the compiled one carries the rows' own tables with the measured point
    (it refused them once, and every thermal fit ran on numpy in a study's workers)."""
    refused: list[bool] = []
    taken = kinematics._compiled_inputs

    def inputs(*args: object) -> object:
        found = taken(*args)  # type: ignore[arg-type]
        refused.append(found is None)
        return found

    monkeypatch.setattr(kinematics, "_compiled_inputs", inputs)
    rng = np.random.default_rng(5)
    q = rng.uniform(-1.5, 1.5, (15, 6))
    model = _model(irb120, kind, ("dh", "transmission", "thermal"))
    data = {"length": lambda: length_measurements(q, np.full(15, 0.8)),
            "position": lambda: position_measurements(q, np.zeros((15, 3))),
            "pose": lambda: pose_measurements(q, np.zeros((15, 3)),
                                              np.broadcast_to(np.eye(3), (15, 3, 3)))}[kind]()
    data = _warm(data, rng.uniform(18.0, 30.0, 15))
    x = rng.normal(0.0, 1e-4, model.n_params)
    x[model.slice("thermal")] = rng.normal(0.0, 1e-5, model.group("thermal").size)
    residuals, jacobian = model.jacobian(x, data)
    step = 1e-7
    numeric = np.stack([(model.residuals(x + step * e, data) - model.residuals(x - step * e, data))
                        / (2 * step) for e in np.eye(model.n_params)], axis=1)
    np.testing.assert_allclose(jacobian, numeric, rtol=0, atol=1e-7)
    assert np.abs(jacobian[:, model.slice("thermal")]).max() > 1.0  # the columns are not empty
    # One x's rows on the compiled kernel where it is taken (it once refused them all).
    assert refused and not any(refused) if kernel == "numba" else not refused
    batch = model.residuals(np.stack([x, 2 * x]), data)
    np.testing.assert_allclose(batch[0], residuals, rtol=0, atol=1e-15)
    np.testing.assert_allclose(batch[1], model.residuals(2 * x, data), rtol=0, atol=1e-15)


def test_each_row_is_read_on_its_own_table(irb120: RobotModel) -> None:
    """The model's point at a row is the core's kinematics of the table grown by the thermal
    unknowns times that row's temperature above the reference, row by row; poses without a
    temperature are at the reference."""
    rng = np.random.default_rng(6)
    q = rng.uniform(-1.5, 1.5, (10, 6))
    model = _model(irb120, "length")
    temperature = rng.uniform(15.0, 35.0, 10)
    data = _warm(length_measurements(q, np.full(10, 0.8)), temperature)
    x = rng.normal(0.0, 1e-4, model.n_params)
    group = model.group("thermal")
    assert group.linear is not None
    growth = x[model.slice("thermal")]
    rows = [point_position(irb120.structure, model.table(x) + (group.linear @ (
        growth * (t - 23.0))).reshape(4, 6), q[k:k + 1])[0] for k, t in enumerate(temperature)]
    np.testing.assert_allclose(model.positions(x, data), rows, rtol=0, atol=1e-15)
    cold = point_position(irb120.structure, model.table(x), q)
    np.testing.assert_allclose(model.positions(x, model.poses(q)), cold, rtol=0, atol=1e-15)


def _simulate(seed: int | None = None, ramp_k: float | None = None) -> Simulation:
    scenario = load_scenario(SCENARIO)
    assert scenario.thermal is not None
    if ramp_k is not None:
        scenario = replace(scenario, thermal=replace(scenario.thermal, ramp_k=ramp_k))
    return simulate(scenario, seed)


@pytest.mark.slow
def test_a_constant_temperature_holds_the_growth_at_zero() -> None:
    """A capture at one temperature cannot see a growth per kelvin: every coefficient is
    held at 0 and named unseen, and the D-H errors are those of the D-H fit alone."""
    sim = _simulate(ramp_k=0.0)
    result = calibrate(sim.robot, sim.measurements, rig=sim.rig_told, settings=THERMAL)
    alone = calibrate(sim.robot, sim.measurements, rig=sim.rig_told)
    model = result.model
    assert model.rig.temperature_ref_c == pytest.approx(20.0)
    np.testing.assert_array_equal(result.solver.x[model.slice("thermal")], 0.0)
    assert result.unseen is not None
    assert {f"k_{name}" for name in ("a1", "a2", "d1", "d4")} <= set(
        " ".join(result.unseen.names).replace("-", " ").replace("+", " ").split())
    np.testing.assert_allclose(result.delta, alone.delta, rtol=0, atol=1e-9)


def _referee(model: Model, train: Measurements) -> np.ndarray:
    """scipy's least_squares (trust-region reflective, its own finite differences) on the same
    training residuals, from the same start."""
    return np.asarray(least_squares(lambda x: model.residuals(x, train),
                                    np.zeros(model.n_params), bounds=model.bounds(),
                                    x_scale="jac", xtol=1e-12, ftol=1e-12, gtol=1e-12).x)


def _held_out(model: Model, q: np.ndarray, reference_c: float) -> list[Measurements]:
    """The held-out poses at the reference temperature and 4 K either side of it."""
    return [_warm(model.poses(q), np.full(len(q), reference_c + shift))
            for shift in (-4.0, 0.0, 4.0)]


def _seen_alone(sim: Simulation, result: CalibrationResult
                ) -> tuple[Model, Measurements, np.ndarray, np.ndarray, list[int]]:
    """A warm-up's calibration against its truth: the model, the training poses, the true
    unknowns, their Cramér–Rao covariance there, and the growths the poses see alone (in no
    null direction) — among them those of the long links, k_a2, k_d1 and k_d4."""
    model = result.model
    train = sim.measurements.subset(result.train_rows)
    x_true = true_unknowns(sim, model)
    covariance = cramer_rao_covariance(model, x_true, train, noise_sigma_m(
        sim, model.jacobian(x_true, train)[1]))
    assert result.identifiability is not None
    null = result.identifiability.null_space
    alone = [i for i in range(model.n_params)[model.slice("thermal")]
             if np.max(np.abs(null[i]), initial=0.0) < 1e-6]
    assert {model.names[i] for i in alone} >= {"k_a2", "k_d1", "k_d4"}
    return model, train, x_true, covariance, alone


@pytest.mark.slow
def test_thermal_recovered_within_twice_the_bound() -> None:
    """Over 6 seeded warm-ups: each growth the data see alone, k_a and k_d, has an RMS error
    against the twin's truth within 2× its Cramér–Rao σ, and the flange at 300 held-out
    workspace poses at the reference temperature and 4 K either side (D-H errors and growth
    together) within 2× its bound; scipy's least_squares on the same residual gives the growth
    and the flange of LM's own minimum (before the unseen directions are held)."""
    errors, bounds, flange, flange_bound = [], [], [], []
    for seed in range(6):
        sim = _simulate(200 + seed)
        result = calibrate(sim.robot, sim.measurements, rig=sim.rig_told, settings=THERMAL,
                           seed=seed)
        model, train, x_true, covariance, alone = _seen_alone(sim, result)
        errors.append(result.solver.x[alone] - x_true[alone])
        bounds.append(np.sqrt(np.diag(covariance))[alone])
        q = random_poses(sim.robot, 300, np.random.default_rng(2024 + seed))
        assert model.rig.temperature_ref_c is not None
        for poses in _held_out(model, q, model.rig.temperature_ref_c):
            flange.append(rms_distance(model.flange_positions(result.solver.x, poses),
                                       model.flange_positions(x_true, poses)))
            flange_bound.append(float(np.sqrt(np.mean(flange_sigma(
                model.flange_jacobian(x_true, poses), covariance) ** 2))))
        if seed == 0:  # the method's own minimum, before the unseen directions are held
            assert result.held is not None
            found, referee = result.held.method_x, _referee(model, train)
            np.testing.assert_allclose(referee[alone], found[alone],
                                       atol=0.1 * float(np.min(bounds[0])))
            poses = _held_out(model, q, model.rig.temperature_ref_c)[2]
            assert rms_distance(model.flange_positions(referee, poses),
                                model.flange_positions(found, poses)) < 0.1 * flange_bound[-1]
    rms = np.sqrt(np.mean(np.square(errors), axis=0))
    bound = np.sqrt(np.mean(np.square(bounds), axis=0))
    assert np.all(rms < 2 * bound), (rms, bound)
    assert np.all(bound < 3e-6)  # µm/K: seen, not guessed
    flange_rms = float(np.sqrt(np.mean(np.square(flange))))
    bound_rms = float(np.sqrt(np.mean(np.square(flange_bound))))
    assert flange_rms < 2 * bound_rms, (flange_rms, bound_rms)


def test_thermal_needs_a_temperature(refusals: Refusals) -> None:
    """--errors thermal on measurements without a temperature_c column: one line, exit 2."""
    path = Path(__file__).resolve().parents[1] / "examples" / "irb120_lm" / "measurements.csv"
    refusals.cli(["calibrate", path, "--port", "600,-400,100", "--errors", "dh,thermal"],
                 [path], "--errors thermal with measurements without a temperature_c column")


@pytest.mark.slow
def test_thermal_runs_through_the_command_line(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    """simulate → calibrate --errors dh,thermal (a Rerun recording) → predict: the report
    shows the growth in µm/K at the data's mean temperature, the result keeps it with the
    reference, Rerun's reader gives back the exact unknowns and the residuals after, and the
    prediction at each row's temperature is within the noise of the readings (a D-H fit's
    would not be)."""
    out = tmp_path / "thermal"
    assert main(["simulate", str(SCENARIO), "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["calibrate", str(out / "capture.toml"), "--errors", "dh,thermal", "--json",
                 str(out / "result.json"), "--rerun-save", str(out / "calibrate.rrd")]) == 0
    report = capsys.readouterr().out
    assert "Identified thermal growth (the D-H lengths are the links' at 24.00 °C" in report
    assert "k_a [µm/K]" in report and "DRIFT beyond the noise" in report
    document = json.loads((out / "result.json").read_text())
    assert document["unknowns"]["rig"]["temperature_ref_c"] == pytest.approx(24.0)
    growth = {p["name"]: p for p in document["unknowns"]["parameters"]
              if p["group"] == "thermal"}
    assert growth["k_d4"]["unit"] == "µm/K" and abs(growth["k_d4"]["value"] - 6.9) < 4.0
    identified = load_result(out / "result.json")
    batches = read_rrd(out / "calibrate.rrd")
    # The result keeps 1e-6 mm and 1e-6 degree: the recording's exact values round to them.
    np.testing.assert_allclose(scalars(batches, entities.parameter_exact("lm")), identified.x,
                               rtol=0, atol=2e-8)
    data = identified.model.kind.prepare(identified.robot, identified.model.rig,
                                         load_measurements_of(out), THERMAL.noise)[1]
    np.testing.assert_allclose(scalars(batches, entities.residuals_after("lm")),
                               1e3 * identified.model.residuals(identified.x, data),
                               rtol=0, atol=1e-4)
    assert main(["predict", "--identified", str(out / "result.json"), "--joints",
                 str(out / "measurements.csv"), "--out", str(out / "predicted.csv")]) == 0
    assert "grown to each row's temperature_c from 24.00 °C" in capsys.readouterr().out
    predicted = np.genfromtxt(out / "predicted.csv", delimiter=",", names=True)["length"]
    read = np.genfromtxt(out / "measurements.csv", delimiter=",", names=True)["length"]
    sigma_mm = 0.01
    assert np.sqrt(np.mean((predicted - read) ** 2)) < 1.5 * sigma_mm
    assert main(["calibrate", str(out / "capture.toml"), "--errors", "dh", "--json",
                 str(out / "rigid.json")]) == 0
    assert main(["predict", "--identified", str(out / "rigid.json"), "--joints",
                 str(out / "measurements.csv"), "--out", str(out / "rigid.csv")]) == 0
    rigid = np.genfromtxt(out / "rigid.csv", delimiter=",", names=True)["length"]
    assert np.sqrt(np.mean((rigid - read) ** 2)) > 2 * sigma_mm


def load_measurements_of(out: Path) -> Measurements:
    from twin.io.measurements import load_measurements
    from twin.io.robot_file import load_robot

    return load_measurements(out / "measurements.csv", load_robot(out / "robot.toml"))


def _pose_warm_up() -> Scenario:
    """The 6-D pose scenario (tracker frame estimated) during the thermal scenario's warm-up."""
    pose = load_scenario(SCENARIO.parent / "pose_irb120.toml")
    return replace(pose, thermal=load_scenario(SCENARIO).thermal,
                   calibration=replace(pose.calibration, errors=("dh", "thermal")))


@pytest.mark.slow
def test_thermal_of_6d_poses_recovered_within_twice_the_bound(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """6-D poses of a warm-up: the growth moves their positions (lengths do not turn the
    flange). Over 4 seeded warm-ups each growth the data see alone has an RMS error against the
    twin's truth within 2× its Cramér–Rao σ; scipy's least_squares on the same residual gives
    LM's own minimum; simulate → calibrate --errors dh,thermal on the command line reports the
    growth."""
    scenario = _pose_warm_up()
    errors, bounds = [], []
    for seed in range(4):
        sim = simulate(scenario, 300 + seed)
        result = calibrate(sim.robot, sim.measurements, rig=sim.rig_told_pulled,
                           settings=scenario.calibration, seed=seed)
        model, train, x_true, covariance, alone = _seen_alone(sim, result)
        assert result.held is not None
        errors.append(result.held.method_x[alone] - x_true[alone])
        bounds.append(np.sqrt(np.diag(covariance))[alone])
        if seed == 0:
            np.testing.assert_allclose(_referee(model, train)[alone],
                                       result.held.method_x[alone],
                                       atol=0.1 * float(np.min(bounds[0])))
    rms = np.sqrt(np.mean(np.square(errors), axis=0))
    bound = np.sqrt(np.mean(np.square(bounds), axis=0))
    assert np.all(rms < 2 * bound), (rms, bound)
    assert np.all(bound < 3e-6)  # µm/K: seen, not guessed
    out = tmp_path / "pose"
    write_simulation(out, simulate(scenario))
    capsys.readouterr()
    assert main(["calibrate", str(out / "capture.toml"), "--errors", "dh,thermal",
                 "--estimate-base"]) == 0
    assert "Identified thermal growth (the D-H lengths are the links' at" in \
        capsys.readouterr().out


def _urdf_flange_m(path: Path, q: np.ndarray) -> np.ndarray:
    """The flange (`tool0`) of a URDF at joint angles q (m, n), read by Pinocchio, (m, 3), m."""
    pin = pytest.importorskip("pinocchio")
    model = pin.buildModelFromUrdf(str(path))
    data, frame = model.createData(), model.getFrameId("tool0")
    found = []
    for pose in q:
        pin.framesForwardKinematics(model, data, pose)
        found.append(data.oMf[frame].translation.copy())
    return np.array(found)


@pytest.mark.slow
def test_a_result_is_exported_and_compensated_at_the_cells_temperature(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A thermal result exported with --temperature-c 10 K above the calibration's mean
    temperature: the URDF, read by Pinocchio, has the table the result's own numbers give at
    that temperature (each length plus its k · 10 K, from the JSON) and puts the flange where
    the twin's true robot, warmed to it, has it — within the calibration's accuracy, where the
    table at the mean temperature is off by the growth. Without the flag the export says the
    links are at the mean temperature; compensating a program at that temperature brings the
    warm robot's flange to the program's nominal poses. A result without growth refuses the
    flag."""
    sim = _simulate()
    thermal = sim.scenario.thermal
    assert thermal is not None
    out = tmp_path / "thermal"
    write_simulation(out, sim)
    result = out / "result.json"
    assert main(["calibrate", str(out / "capture.toml"), "--json", str(result)]) == 0
    reference = json.loads(result.read_text())["unknowns"]["rig"]["temperature_ref_c"]
    warm_c = reference + 10.0
    capsys.readouterr()
    assert main(["export", str(result), "--format", "urdf", "--out",
                 str(tmp_path / "ref.urdf")]) == 0
    assert re.search(r"twin: warning: .*the urdf file holds the links at 24.00 °C.*"
                     r"--temperature-c T", capsys.readouterr().err)
    assert main(["export", str(result), "--format", "urdf", "--out", str(tmp_path / "warm.urdf"),
                 "--temperature-c", f"{warm_c}"]) == 0
    printed = capsys.readouterr()
    assert "(identified, at 34.00 °C)" in printed.out and "holds the links" not in printed.err
    q = random_poses(sim.robot, 200, np.random.default_rng(5))
    # The referee: the result's table grown by its own k, read from the JSON (µm/K).
    loaded = load_result(result)
    growth = {p["name"]: p["value"] * 1e-6 for p in
              json.loads(result.read_text())["unknowns"]["parameters"] if p["group"] == "thermal"}
    table = loaded.model.table(loaded.x).copy()
    for slot, key in enumerate("ad"):
        for joint in range(sim.robot.n_joints):
            table[slot, joint] += growth.get(f"k_{key}{joint + 1}", 0.0) * 10.0
    expected = replace(sim.robot, dh=table).flange_positions(q)
    np.testing.assert_allclose(_urdf_flange_m(tmp_path / "warm.urdf", q), expected, rtol=0,
                               atol=1e-8)
    truth = sim.true_robot.perturbed(thermal.growth(warm_c)).flange_positions(q)
    warm_error = rms_distance(_urdf_flange_m(tmp_path / "warm.urdf", q), truth)
    cold_error = rms_distance(_urdf_flange_m(tmp_path / "ref.urdf", q), truth)
    assert warm_error < 0.5 * cold_error and warm_error < 0.04e-3, (warm_error, cold_error)

    program = out / "program.csv"
    program.write_text("q1,q2,q3,q4,q5,q6\n" + "\n".join(
        ",".join(f"{v:.6f}" for v in np.degrees(row)) for row in q[:40]) + "\n")
    corrected = tmp_path / "corrected.csv"
    assert main(["compensate", "--identified", str(result), "--joints", str(program),
                 "--out", str(corrected), "--temperature-c", f"{warm_c}"]) == 0
    with corrected.open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    ok = np.array([row["status"] == "ok" for row in rows])
    commanded = np.deg2rad([[float(row[f"q{k}"]) for k in range(1, 7)]
                            for row, good in zip(rows, ok, strict=True) if good])
    warm_robot = sim.true_robot.perturbed(thermal.growth(warm_c))
    reached = rms_distance(warm_robot.flange_positions(commanded),
                           sim.robot.flange_positions(q[:40][ok]))
    uncompensated = rms_distance(warm_robot.flange_positions(q[:40]),
                                 sim.robot.flange_positions(q[:40]))
    assert ok.sum() >= 25 and reached < 0.04e-3 < 0.1 * uncompensated, (reached, uncompensated)
    assert main(["calibrate", str(out / "capture.toml"), "--errors", "dh", "--json",
                 str(out / "rigid.json")]) == 0
    assert main(["export", str(out / "rigid.json"), "--format", "urdf", "--out",
                 str(tmp_path / "x.urdf"), "--temperature-c", "30"]) == 2
    assert "a result without thermal growth" in capsys.readouterr().err
    assert not (tmp_path / "x.urdf").exists()


def test_errors_auto_tries_the_growth_of_a_warm_up(irb120: RobotModel) -> None:
    """--errors auto adds thermal growth right after the D-H table when the measurements'
    temperature changes, and says why it does not otherwise: no temperature_c, one that
    stays put; 6-D poses take it too."""
    q = random_poses(irb120, 20, np.random.default_rng(3))
    lengths = length_measurements(q, np.ones(20))
    warm = _warm(lengths, np.linspace(20.0, 28.0, 20))
    assert _warming(warm) is None
    assert nested_errors(False, True)[:3] == [("dh",), ("dh", "thermal"),
                                               ("dh", "thermal", "compliance")]
    assert all("thermal" not in errors for errors in nested_errors(True, False))
    assert "no temperature_c" in str(_warming(lengths))
    assert "changes by 0.05 K only" in str(_warming(_warm(lengths, np.linspace(20, 20.05, 20))))
    poses = _model(irb120, "pose", ("dh",)).measure(np.zeros(24), q)
    assert _warming(_warm(poses, np.linspace(20.0, 28.0, 20))) is None


@pytest.mark.slow
def test_errors_auto_chooses_the_growth_on_a_warm_up(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """On the thermal scenario's capture (8 K over the capture) --errors auto fits D-H alone,
    then with the growth and the joint-level groups on top, and chooses D-H + thermal: the
    lowest BIC, and the lowest validation RMSE."""
    out = tmp_path / "thermal"
    write_simulation(out, _simulate())
    assert main(["calibrate", str(out / "capture.toml"), "--errors", "auto", "--json",
                 str(out / "auto.json")]) == 0
    assert "dh+thermal " in capsys.readouterr().out
    candidates = json.loads((out / "auto.json").read_text())["error_choice"]["candidates"]
    assert [c["errors"] for c in candidates][:3] == [["dh"], ["dh", "thermal"],
                                                     ["dh", "thermal", "compliance"]]
    chosen = [c for c in candidates if c["chosen"]]
    assert [c["errors"] for c in chosen] == [["dh", "thermal"]]
    assert chosen[0]["bic"] == min(c["bic"] for c in candidates)
    validation = [c["validation_rmse"] for c in candidates]
    assert chosen[0]["validation_rmse"] == min(validation), validation


@pytest.mark.slow
def test_identify_scores_a_warm_up_at_its_temperatures(tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    """`twin identify` on a warm-up's capture reports the growth with its σ, and scores the
    poses as they were read, each at its own temperature: the growths' columns are the rises,
    not zeros (which gave O1 = 0, an infinite condition and numpy's divide-by-zero warnings);
    the indices equal those of the base columns of the Jacobian the test takes itself, on the
    capture's rows."""
    sim = _simulate()
    out = tmp_path / "thermal"
    write_simulation(out, sim)
    capsys.readouterr()
    assert main(["identify", str(out / "capture.toml"), "--json", str(out / "id.json")]) == 0
    printed = capsys.readouterr()
    assert "divide by zero" not in printed.err
    assert "Identified thermal growth (the D-H lengths are the links' at 24.00 °C" in printed.out
    assert "k_a [µm/K]       ±σ" in printed.out
    nominal = json.loads((out / "id.json").read_text())["nominal"]
    data = load_measurements_of(out)
    model = make_model(sim.robot, replace(sim.rig_told_pulled, temperature_ref_c=float(
        np.mean(data.value(TEMPERATURE)))), "length", THERMAL)
    base = [model.names.index(name) for name in nominal["base"]]
    singular = np.linalg.svd(model.jacobian(np.zeros(model.n_params), data)[1][:, base],
                             compute_uv=False)
    assert nominal["observability"]["condition"] == pytest.approx(singular[0] / singular[-1],
                                                                  rel=1e-6)
    assert nominal["observability"]["o1"] == pytest.approx(
        np.exp(np.mean(np.log(singular))) / np.sqrt(len(data)), rel=1e-6)
