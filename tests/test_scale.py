"""The encoder's scale (twin.unknowns.scale, read by twin.kinds.length): every modelled length is
(1 + s) times the cable's, the analytic Jacobian equals central differences, the twin's
encoder reads with the scale its scenario states, the misfit test flags a 100 ppm scale the
calibration does not estimate and is quiet when it does, and the scale and the D-H errors are
recovered.

The recovery is held to the twin's ground truth — the scale within 2× its Cramér–Rao σ over
trials, the flange and the encoder's readings over held-out workspace poses within 2× their
bounds — and to an independent referee computed here: scipy.optimize.least_squares on the same
residual over the directions the answer leaves free.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.stats import chi2

from tests.test_viz_rerun import column, read_rrd, scalars
from twin.analysis.misfit import ALPHA
from twin.analysis.uncertainty import cramer_rao_covariance, cramer_rao_flange_rms, rms_distance
from twin.calibration.pipeline import CalibrationResult, calibrate
from twin.calibration.settings import CalibrationSettings
from twin.calibration.setup import make_model
from twin.cli import main
from twin.dataset import Measurements
from twin.errors import InputError
from twin.io.measurements import load_measurements
from twin.model import Model
from twin.rig import Rig
from twin.robot import RobotModel, random_poses
from twin.scenario import load_scenario
from twin.sim import Simulation, simulate
from twin.study.trial import noise_sigma_m, true_unknowns
from twin.viz import entities

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "scale_irb120.toml"
PPM = 1e-6
TRIALS = 6
WORKSPACE = 300


def _numeric(function, x: np.ndarray, eps: float = 1e-7) -> np.ndarray:
    steps = np.eye(x.size) * eps
    return np.moveaxis((function(x + steps) - function(x - steps)) / (2 * eps), 0, -1)


def _model(robot: RobotModel, port_m: np.ndarray, estimate: tuple[str, ...]) -> Model:
    return make_model(robot, Rig.cable(port_m), settings=CalibrationSettings(estimate=estimate))


@pytest.mark.parametrize("estimate", [("scale",), ("port", "offset", "scale")])
def test_scale_jacobian_matches_differences(irb120: RobotModel, measurements: Measurements,
                                            port_m: np.ndarray, estimate: tuple[str, ...]
                                            ) -> None:
    """∂r/∂x of the D-H errors, the port, the offset and the scale equals central
    differences, away from x = 0 (a scale of 3000 ppm: the gain multiplies ∂r/∂p and ∂r/∂δP)."""
    model = _model(irb120, port_m, estimate)
    data = measurements.subset(np.arange(15))
    rng = np.random.default_rng(5)
    x = rng.normal(scale=1e-3, size=model.n_params)
    x[model.slice("scale")] = 3000 * PPM
    r, jacobian = model.jacobian(x, data)
    np.testing.assert_allclose(r, model.residuals(x, data), atol=1e-14)
    np.testing.assert_allclose(jacobian, _numeric(lambda xs: model.residuals(xs, data), x),
                               atol=1e-8)


def test_the_scale_multiplies_every_length_before_the_offset(
        irb120: RobotModel, measurements: Measurements, port_m: np.ndarray) -> None:
    """A reading is (1 + s) · ‖p − P‖ + c: 100 ppm and 2 mm on the cable lengths."""
    model = _model(irb120, port_m, ("offset", "scale"))
    x = np.zeros(model.n_params)
    x[model.slice("offset")], x[model.slice("scale")] = 0.002, 100 * PPM
    plain = np.linalg.norm(irb120.flange_positions(measurements.q_rad) - port_m, axis=-1)
    read = model.measure(x, measurements.q_rad).value("length_m")
    np.testing.assert_allclose(read, (1 + 100 * PPM) * plain + 0.002, atol=1e-15)


def test_the_twins_encoder_reads_with_its_scale(tmp_path: Path) -> None:
    """[encoder] scale_ppm: the twin's readings are 1.0001 times the true cable lengths (its
    noise aside); truth.json states the scale; a scale beyond ±5000 ppm or not a number is
    refused in one line naming the key."""
    scenario = load_scenario(SCENARIO)
    quiet = replace(scenario, noise=replace(scenario.noise, sigma_m=0.0))
    sim = simulate(quiet, 0)
    read = sim.measurements.value("length_m")
    true = np.linalg.norm(sim.true_robot.flange_positions(sim.measurements.q_rad)
                          - sim.rig.ports_m[0], axis=1)
    np.testing.assert_allclose(read / true - 1, 100 * PPM, atol=1e-9)
    assert quiet.noise.to_dict()["scale_ppm"] == pytest.approx(100.0)
    for value, found in (("1e5", "100000.0"), ('"big"', "'big'")):
        path = tmp_path / "bad.toml"
        path.write_text(SCENARIO.read_text().replace("scale_ppm = 100.0", f"scale_ppm = {value}")
                        .replace('"../models/', f'"{ROOT}/models/'))
        with pytest.raises(InputError, match=rf"\[encoder\] scale_ppm: found {found}, expected "
                           r"a scale error in ppm within ±5000$"):
            load_scenario(path)


def _simulate(seed: int | None = None) -> Simulation:
    return simulate(load_scenario(SCENARIO), seed)


def _calibrate(sim: Simulation, estimate: tuple[str, ...], seed: int = 0) -> CalibrationResult:
    settings = replace(sim.scenario.calibration, estimate=estimate)
    return calibrate(sim.robot, sim.measurements, rig=sim.rig_told, method="lm",
                     settings=settings, seed=seed)


@pytest.mark.slow
def test_misfit_flags_an_unestimated_scale_and_is_quiet_when_it_is_estimated() -> None:
    """On the twin with a 100 ppm scale (three seeds): without --estimate-scale the χ² test
    rejects the fit (p < 0.001, the test's level), with it the p-value is above the level."""
    for seed in range(3):
        sim = _simulate(seed)
        for estimate, rejected in (((), True), (("scale",), False)):
            misfit = _calibrate(sim, estimate, seed).misfit
            assert misfit is not None
            p_value = float(chi2.sf(misfit.statistic, misfit.dof))
            assert misfit.misfit is rejected, (seed, estimate, p_value)
            assert (p_value < ALPHA) is rejected, (seed, estimate, p_value)


def _referee(model: Model, train: Measurements, result: CalibrationResult) -> np.ndarray:
    """scipy's least_squares (its own trust region) on the same training residuals, over the
    directions the answer leaves free (what the data cannot see is held at the nominal)."""
    assert result.unseen is not None
    free = result.unseen.seen_x
    found = least_squares(lambda z: model.residuals(free @ z, train), np.zeros(free.shape[1]),
                          jac=lambda z: model.jacobian(free @ z, train)[1] @ free,
                          method="trf", x_scale="jac", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    return np.asarray(free @ found.x)


def _reading_bound(model: Model, x_true: np.ndarray, covariance: np.ndarray, q: np.ndarray
                   ) -> float:
    """The Cramér–Rao bound of the RMS error of the encoder's modelled readings at poses q, m:
    the readings' Jacobian there with the training poses' covariance."""
    rows = model.jacobian(x_true, model.poses(q))[1]
    return float(np.sqrt(np.mean(np.einsum("ij,jk,ik->i", rows, covariance, rows))))


@pytest.mark.slow
def test_scale_and_dh_errors_are_recovered_within_twice_their_bound() -> None:
    """Over 6 trials of the scale scenario (port told, scale and D-H errors estimated): the
    scale's RMS error against the twin's truth is within 2× its Cramér–Rao σ; at 300 held-out
    workspace poses the flange and the encoder's readings (the twin's true lengths times its
    true gain) are within 2× their bounds; scipy's least_squares on the same residual lands on
    the same scale and the same flange, to a tenth of their bounds."""
    errors, bounds = [], []
    q = random_poses(load_scenario(SCENARIO).robot, WORKSPACE, np.random.default_rng(2026))
    for trial in range(TRIALS):
        sim = _simulate(300 + trial)
        result = _calibrate(sim, ("scale",), trial)
        model, train = result.model, sim.measurements.subset(result.train_rows)
        x_true = true_unknowns(sim, model)
        sigma = noise_sigma_m(sim, model.jacobian(x_true, train)[1])
        covariance = cramer_rao_covariance(model, x_true, train, sigma)
        i = model.slice("scale").start
        errors.append(result.x[i] - x_true[i])
        bounds.append(np.sqrt(covariance[i, i]))
        if trial:
            continue
        flange_bound = cramer_rao_flange_rms(model, x_true, train, sigma, q)
        at = model.poses(q)
        truth = sim.true_robot.flange_positions(q)
        assert rms_distance(model.flange_positions(result.x, at), truth) < 2 * flange_bound
        true_read = (1 + sim.scenario.noise.scale) * np.linalg.norm(
            truth - sim.rig.ports_m[0], axis=1)
        reading_error = np.sqrt(np.mean((model.measure(result.x, q).value("length_m")
                                         - true_read) ** 2))
        reading_bound = _reading_bound(model, x_true, covariance, q)
        assert reading_error < 2 * reading_bound, (reading_error, reading_bound)
        referee = _referee(model, train, result)
        assert abs(referee[i] - result.x[i]) < 0.1 * bounds[0]
        assert rms_distance(model.flange_positions(referee, at),
                            model.flange_positions(result.x, at)) < 0.1 * flange_bound
    rms, bound = np.sqrt(np.mean(np.square(errors))), np.sqrt(np.mean(np.square(bounds)))
    assert rms < 2 * bound, (rms / PPM, bound / PPM)
    assert bound < 10 * PPM  # seen, not guessed: a few ppm at σ = 0.01 mm


def test_an_estimated_port_cannot_see_the_scale(irb120: RobotModel, port_m: np.ndarray) -> None:
    """With the port estimated too, a common scale of every length (the table's, the port's
    distance from the base) and the encoder's gain are one direction no cable length moves
    along: the identifiability names the scale among what the data cannot see."""
    from twin.analysis.identifiability import measurement_identifiability

    model = _model(irb120, port_m, ("port", "scale"))
    q = random_poses(irb120, 120, np.random.default_rng(3))
    unseen = " ".join(measurement_identifiability(model, np.zeros(model.n_params),
                                                  model.poses(q)).unidentifiable)
    assert "scale" in unseen, unseen


@pytest.mark.slow
def test_scale_runs_through_the_command_line(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    """twin simulate → calibrate (with a Rerun recording) → predict → export on the scale
    scenario: the report and the result give the scale in ppm with its σ, the predicted cable
    lengths carry it (within the noise of the readings), the robot file does not; the same
    data calibrated without the scale are a misfit the diagnosis puts on the scale."""
    out = tmp_path / "scale"
    assert main(["simulate", str(SCENARIO), "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["calibrate", str(out / "capture.toml"), "--json", str(out / "result.json"),
                 "--rerun-save", str(out / "calibrate.rrd")]) == 0
    report = capsys.readouterr().out
    assert "identified encoder scale: +" in report and " ppm ± " in report, report
    batches = read_rrd(out / "calibrate.rrd")
    poses = len((out / "measurements.csv").read_text().splitlines()) - 1
    assert len(column(batches, entities.CABLE, entities.POSE_TIMELINE)) == poses
    assert scalars(batches, entities.residuals_after("lm")).shape == (poses,)
    document = json.loads((out / "result.json").read_text())
    truth_ppm = json.loads((out / "truth.json").read_text())["noise"]["scale_ppm"]
    assert abs(document["scale_ppm"] - truth_ppm) < 3 * document["sigma"]["scale_ppm"]
    names = [entry["name"] for entry in document["unknowns"]["parameters"]]
    assert "scale" in names
    assert main(["predict", "--identified", str(out / "result.json"), "--joints",
                 str(out / "measurements.csv"), "--out", str(out / "predicted.csv")]) == 0
    predicted = np.genfromtxt(out / "predicted.csv", delimiter=",", names=True)["length"]
    read_mm = 1e3 * load_measurements(out / "measurements.csv").value("length_m")
    scatter = np.sqrt(np.mean((predicted - read_mm) ** 2))
    assert scatter < 2 * load_scenario(SCENARIO).noise.sigma_m * 1e3, scatter
    assert main(["export", str(out / "result.json"), "--format", "dh",
                 "--out", str(out / "robot.toml")]) == 0
    assert "scale" not in (out / "robot.toml").read_text()
    capsys.readouterr()
    assert main(["calibrate", str(out / "measurements.csv"), "--port", "600,-400,100",
                 "--sigma", "0.01"]) == 0
    report = capsys.readouterr().out
    assert "MISFIT" in report and "the encoder's scale (--estimate-scale reaches" in report
