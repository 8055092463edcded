"""Real rigs in the twin: an eyelet off the flange, a laser tracker, a ball fixture, encoder
stations with unknown ports, outliers under a robust loss, and a misfit that is reported.

Each recovery is held to the twin's ground truth (within 2× the Cramér–Rao bound of what the
data identify) and to an independent referee computed here: scipy.optimize.least_squares on
the same residual (its own trust-region method, finite-difference Jacobian, its own robust
loss), which must predict the same points.
"""

from __future__ import annotations

import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import least_squares

from twin.analysis.gauge import gauge_free_rms, unobservable_motions
from twin.analysis.uncertainty import (
    cramer_rao_covariance,
    cramer_rao_flange_rms,
    cramer_rao_rms,
    predicted_flange_rms,
    rms_distance,
)
from twin.calibration.accuracy import rigid_truth, truth_errors
from twin.calibration.pipeline import calibrate, solve_many
from twin.calibration.result import CalibrationResult
from twin.calibration.selection import FewPosesWarning, warn_few_poses
from twin.calibration.settings import CalibrationSettings
from twin.calibration.setup import make_problem
from twin.cli import main
from twin.io.robot_file import load_robot
from twin.loss import Loss
from twin.model import Model
from twin.robot import random_poses
from twin.scenario import load_scenario
from twin.sim import Simulation, simulate
from twin.study.trial import noise_sigma_m, true_unknowns

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
JOINT_1 = ("rotation about joint 1's axis", "shift along joint 1's axis")


def _simulate(name: str) -> Simulation:
    return simulate(load_scenario(SCENARIOS / f"{name}.toml"))


def _calibrate(sim: Simulation, loss: Loss | None = None) -> CalibrationResult:
    settings = CalibrationSettings(estimate=sim.scenario.calibration.estimate)
    if loss is not None:
        settings = replace(settings, loss=loss.name, loss_scale_m=loss.scale_m)
    return calibrate(sim.robot, sim.measurements, rig=sim.rig_told, method="lm",
                     settings=settings)


def _referee(result: CalibrationResult, sim: Simulation, loss: str = "linear",
             scale_m: float = 1.0) -> np.ndarray:
    """scipy's least_squares on the result's own training residuals, from the same start."""
    model = result.model
    train = sim.measurements.subset(result.train_rows)
    lower, upper = model.bounds()
    solved = least_squares(lambda x: model.residuals(x, train), np.zeros(model.n_params),
                           bounds=(lower, upper), loss=loss, f_scale=scale_m,
                           x_scale="jac", xtol=1e-12, ftol=1e-12, gtol=1e-12)
    return np.asarray(solved.x)


def _workspace(sim: Simulation) -> np.ndarray:
    return random_poses(sim.robot, 500, np.random.default_rng(2024))


def _bound(result: CalibrationResult, sim: Simulation, q: np.ndarray, point: bool = False
           ) -> float:
    """The Cramér–Rao bound of the flange (or measured point) error over poses q, for the
    result's training poses and the twin's noise, at the true unknowns."""
    model = result.model
    train = sim.measurements.subset(result.train_rows)
    x_true = true_unknowns(sim, model)
    sigma = noise_sigma_m(sim, model.jacobian(x_true, train)[1])
    return cramer_rao_rms(model, x_true, train, sigma, q)[1 if point else 0]


def _gauge_free_points(model: Model, x: np.ndarray, null: np.ndarray, q: np.ndarray,
                       truth: np.ndarray) -> float:
    return gauge_free_rms(unobservable_motions(model, x, null, q, measured=True), truth)


def _true_points(sim: Simulation, q: np.ndarray) -> np.ndarray:
    transforms = sim.true_robot.flange_transforms(q)
    return transforms[:, :3, :3] @ sim.rig.attachment_m + transforms[:, :3, 3]


@pytest.mark.parametrize(("name", "at_flange"),
                         [("geometric_irb120", True), ("eyelet_irb120", False)])
def test_a_point_at_the_flange_is_worked_out_once_as_its_own_chain_would(name: str,
                                                                         at_flange: bool) -> None:
    """A measured point at the flange centre (no attachment, none estimated) takes the flange's
    bound and gauge instead of working them out again: they agree with the point's own chain
    (its Jacobian, its gauge) worked out here. An estimated eyelet is not the flange."""
    sim = _simulate(name)
    result = _calibrate(sim)
    model, x = result.model, result.solver.x
    assert model.measures_flange is at_flange
    q = _workspace(sim)
    poses = model.poses(q)
    apart = float(np.max(np.abs(model.position_jacobian(x, poses)
                                - model.flange_jacobian(x, poses))))
    assert (apart <= 1e-12) is at_flange, apart
    assert result.identified_identifiability is not None
    null = result.identified_identifiability.null_space
    errors = truth_errors(result, *rigid_truth(sim.true_robot, sim.rig.attachment_m, q), q)
    assert errors.point_gauge_free_m == pytest.approx(
        _gauge_free_points(model, x, null, q, _true_points(sim, q)), rel=1e-9, abs=1e-15)
    train = sim.measurements.subset(result.train_rows)
    x_true = true_unknowns(sim, model)
    sigma = noise_sigma_m(sim, model.jacobian(x_true, train)[1])
    covariance = cramer_rao_covariance(model, x_true, train, sigma)
    own = predicted_flange_rms(model.position_jacobian(x_true, poses), covariance)
    assert cramer_rao_rms(model, x_true, train, sigma, q)[1] == pytest.approx(own, rel=1e-12)


@pytest.mark.slow
def test_an_eyelet_off_the_flange_is_found() -> None:
    """The eyelet at (25, −15, 40) mm, told the flange centre and estimated: its predicted
    position over the workspace is within 2× its Cramér–Rao bound, the referee predicts the
    same, and identifiability names what the eyelet trades with (a6, d6, θ6)."""
    sim = _simulate("eyelet_irb120")
    result = _calibrate(sim)
    q = _workspace(sim)
    error = rms_distance(result.model.positions(result.solver.x, result.model.poses(q)),
                         _true_points(sim, q))
    bound = _bound(result, sim, q, point=True)
    assert error < 2 * bound, (error, bound)
    referee = _referee(result, sim)
    poses = result.model.poses(q)
    assert rms_distance(result.model.positions(referee, poses),
                        result.model.positions(result.solver.x, poses)) < 0.2 * bound
    assert result.identifiability is not None
    unseen = result.identifiability.unidentifiable
    assert {"a6-attachment_x", "d6-attachment_z", "theta6"} <= set(unseen), unseen
    assert result.misfit is not None and not result.misfit.misfit


@pytest.mark.slow
def test_the_eyelet_unestimated_is_a_misfit() -> None:
    """The same data with the attachment left at the flange centre do not fit, and the first
    likely cause named is the attachment point."""
    from twin.calibration.diagnosis import likely_causes

    sim = _simulate("eyelet_irb120")
    split = make_problem(sim.robot, sim.measurements, rig=sim.rig_told)
    (result,) = solve_many(sim.robot, split, ["lm"]).values()
    assert result.misfit is not None and result.misfit.misfit
    assert result.misfit.rmse_m > 1e-3
    causes = likely_causes(split, result)
    assert causes[0].name == "the attachment point" and causes[0].refit_rmse_m is not None
    assert causes[0].refit_rmse_m < 2 * result.misfit.noise_m


@pytest.mark.slow
def test_a_port_50_mm_off_is_reported_as_a_misfit() -> None:
    """Told a port 50 mm off, the calibration reports a misfit naming the port first; told
    the right one it does not."""
    from twin.calibration.diagnosis import likely_causes

    sim = _simulate("geometric_irb120")
    assert sim.port_m is not None
    right = calibrate(sim.robot, sim.measurements, sim.port_m)
    assert right.misfit is not None and not right.misfit.misfit
    wrong_port = sim.port_m + np.array([0.05, 0.0, 0.0])
    split = make_problem(sim.robot, sim.measurements, wrong_port)
    (wrong,) = solve_many(sim.robot, split, ["lm"]).values()
    assert wrong.misfit is not None and wrong.misfit.misfit
    assert wrong.misfit.statistic > wrong.misfit.threshold
    assert likely_causes(split, wrong)[0].name == "the port position"


@pytest.mark.slow
def test_tracker_positions_recover_the_target_and_the_frame() -> None:
    """Tracker data with an unknown tracker frame and target: the target's predicted position
    modulo the unobservable motions (named: the turn about and shift along joint 1's axis) is
    within 2× its bound; so is the flange's gauge-free error; the referee agrees."""
    sim = _simulate("tracker_irb120")
    result = _calibrate(sim)
    q = _workspace(sim)
    errors = truth_errors(result, *rigid_truth(sim.true_robot, sim.rig.attachment_m, q), q)
    assert errors.point_motions == JOINT_1
    bound = _bound(result, sim, q, point=True)
    assert errors.point_gauge_free_m < 2 * bound, (errors, bound)
    assert errors.point_m > 10 * bound  # raw, the frame's unseen part dominates
    model = result.model
    flange_bound = _bound(result, sim, q)
    assert errors.flange_gauge_free_m < 2 * flange_bound, (errors, flange_bound)
    referee = _referee(result, sim)
    assert result.identified_identifiability is not None
    null = result.identified_identifiability.null_space
    assert _gauge_free_points(model, referee, null, q, _true_points(sim, q)) < 2 * bound


@pytest.mark.slow
def test_fixed_points_predict_the_tool_point_on_new_configurations() -> None:
    """A ball bar (sockets 50 mm apart) at three places: the ball's predicted position on
    held-out configurations, modulo the turn about and shift along joint 1's axis, is within 2×
    its bound; without the known distances the scale is unobservable too."""
    sim = _simulate("fixed_points_irb120")
    result = _calibrate(sim)
    q = _workspace(sim)  # configurations no touch used
    errors = truth_errors(result, *rigid_truth(sim.true_robot, sim.rig.attachment_m, q), q)
    assert errors.point_motions == JOINT_1
    bound = _bound(result, sim, q, point=True)
    assert errors.point_gauge_free_m < 2 * bound, (errors, bound)
    referee = _referee(result, sim)
    assert result.identified_identifiability is not None
    null = result.identified_identifiability.null_space
    assert _gauge_free_points(result.model, referee, null, q, _true_points(sim, q)) \
        < 2 * bound
    loose = calibrate(sim.robot, sim.measurements, rig=replace(sim.rig_told, distances=()),
                      settings=CalibrationSettings(estimate=('attachment',)))
    assert loose.gauge is not None
    assert "scale about the base origin" in loose.gauge.names


def test_the_unknown_port_regime_is_within_the_bound_modulo_the_gauge() -> None:
    """An estimated port: the raw flange error is mm, the error modulo the motions the data
    cannot see (named: the turn about and shift along joint 1's axis) is within 2× the bound."""
    sim = _simulate("unknown_port_irb120")
    result = _calibrate(sim)
    assert result.gauge is not None and result.gauge.names == JOINT_1
    q = _workspace(sim)
    errors = truth_errors(result, *rigid_truth(sim.true_robot, sim.rig.attachment_m, q), q)
    bound = _bound(result, sim, q)
    assert errors.flange_gauge_free_m < 2 * bound < errors.flange_m, (errors, bound)


@pytest.mark.slow
def test_stations_with_unknown_ports() -> None:
    """Three stations, every port estimated: gauge-free flange error within 2× the bound, the
    referee's likewise, and rows from each station."""
    sim = _simulate("stations_irb120")
    assert sim.measurements.names("port") == ("front", "left", "back")
    assert np.bincount(sim.measurements.index("port")).tolist() == [40, 40, 40]
    result = _calibrate(sim)
    q = _workspace(sim)
    errors = truth_errors(result, *rigid_truth(sim.true_robot, sim.rig.attachment_m, q), q)
    bound = _bound(result, sim, q)
    assert errors.motions == JOINT_1
    assert errors.flange_gauge_free_m < 2 * bound, (errors, bound)
    referee = _referee(result, sim)
    assert result.identified_identifiability is not None
    null = result.identified_identifiability.null_space
    flange = unobservable_motions(result.model, referee, null, q)
    assert gauge_free_rms(flange, sim.true_robot.flange_positions(q)) < 2 * bound


@pytest.mark.slow
@pytest.mark.parametrize("loss", ["huber", "cauchy"])
def test_outliers_are_rejected_and_the_fit_reaches_the_bound(loss: str) -> None:
    """The outliers regime (5 % of readings off by ±0.5–1.5 mm) under a robust loss: the
    flange is within 2× the noise-only bound, the planted outliers are the rejected rows
    (recall and precision 1), and scipy's own robust least squares agrees."""
    sim = _simulate("outliers_irb120")
    scale = 3e-5
    result = _calibrate(sim, Loss(loss, scale))
    planted = set(sim.outlier_rows.tolist())
    rejected = set(result.rejected_rows.tolist())
    assert planted, "the scenario plants outliers"
    recall = len(planted & rejected) / len(planted)
    precision = len(planted & rejected) / max(len(rejected), 1)
    assert recall == 1.0 and precision == 1.0, (sorted(planted), sorted(rejected))
    q = _workspace(sim)
    model = result.model
    train = sim.measurements.subset(result.train_rows)
    x_true = true_unknowns(sim, model)
    clean = train.subset(np.flatnonzero(~np.isin(result.train_rows, sim.outlier_rows)))
    sigma = noise_sigma_m(sim, model.jacobian(x_true, clean)[1])
    bound = cramer_rao_flange_rms(model, x_true, clean, sigma, q)
    true_flange = sim.true_robot.flange_positions(q)
    error = rms_distance(model.flange_positions(result.solver.x, model.poses(q)), true_flange)
    assert error < 2 * bound, (error, bound)
    referee = _referee(result, sim, loss, scale)
    assert rms_distance(model.flange_positions(referee, model.poses(q)), true_flange) \
        < 2 * bound
    plain = _calibrate(sim)
    assert rms_distance(model.flange_positions(plain.solver.x, model.poses(q)),
                        true_flange) > 5 * bound
    assert plain.misfit is not None and plain.misfit.misfit


def test_filters_read_the_loss_as_their_noise_model() -> None:
    """The EKF with a Huber loss reaches the flange within 2× the noise-only bound on the
    outliers regime; without it, it does not."""
    sim = _simulate("outliers_irb120")
    q = _workspace(sim)
    true_flange = sim.true_robot.flange_positions(q)
    errors, bound = {}, 0.0
    for loss in (Loss("huber", 3e-5), Loss()):
        result = calibrate(sim.robot, sim.measurements, sim.port_nominal_m, method="ekf",
                           settings=CalibrationSettings(loss=loss.name, loss_scale_m=loss.scale_m))
        model = result.model
        errors[loss.name] = rms_distance(model.flange_positions(result.solver.x,
                                                                model.poses(q)), true_flange)
        train = sim.measurements.subset(result.train_rows)
        clean = train.subset(np.flatnonzero(~np.isin(result.train_rows, sim.outlier_rows)))
        x_true = true_unknowns(sim, model)
        bound = cramer_rao_flange_rms(model, x_true, clean,
                                      noise_sigma_m(sim, model.jacobian(x_true, clean)[1]), q)
    assert errors["huber"] < 2 * bound < errors["linear"], (errors, bound)


def test_the_few_poses_rule_counts_readings() -> None:
    """A tracker pose gives three readings: 48 poses are plenty for 33 unknowns (144 readings
    for the 99 the rule asks), 32 are not (96); one reading per cable pose."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warn_few_poses(48, 33, ("dh",), rows_per_pose=3)
    with pytest.warns(FewPosesWarning, match=r"32 training poses \(96 readings\).*at least 33"):
        warn_few_poses(32, 33, ("dh",), rows_per_pose=3)
    with pytest.warns(FewPosesWarning, match="at least 72"):
        warn_few_poses(48, 24, ("dh",))


@pytest.mark.slow
def test_predict_gives_what_the_tracker_reads(tmp_path: Path) -> None:
    """`twin predict` on a tracker result writes the target in the tracker frame
    (tracker_x,y,z) beside the base frame: against the twin's noise-free truth it is within the
    noise σ = 0.01 mm RMS on the poses measured (the tracker frame is what the tracker sees: no
    gauge), and the readings scatter about it by σ."""
    sim = _simulate("tracker_irb120")
    capture = tmp_path / "capture"
    assert main(["simulate", str(SCENARIOS / "tracker_irb120.toml"), "--out", str(capture)]) == 0
    result = tmp_path / "result.json"
    assert main(["calibrate", str(capture / "capture.toml"), "--json", str(result)]) == 0
    out = tmp_path / "pred.csv"
    assert main(["predict", "--identified", str(result), "--joints",
                 str(capture / "measurements.csv"), "--out", str(out)]) == 0
    table = np.genfromtxt(out, delimiter=",", names=True)
    assert "length" not in table.dtype.names
    tracker_mm = np.stack([table[f"tracker_{a}"] for a in "xyz"], axis=1)
    frame = sim.rig.base_in_tracker
    truth_mm = 1e3 * (sim.true_points_m @ frame[:3, :3].T + frame[:3, 3])
    assert rms_distance(tracker_mm, truth_mm) / np.sqrt(3) < 0.01
    read_mm = 1e3 * sim.measurements.value("position_m")
    scatter = rms_distance(tracker_mm, read_mm) / np.sqrt(3)
    assert 0.5 * 0.01 < scatter < 1.5 * 0.01, scatter


@pytest.mark.slow
def test_export_and_compensate_say_what_the_data_could_not_pin(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """With the eyelet estimated the flange is seen only up to a shift along its own axes, and
    with it measured, up to a turn about it: export, predict and compensate each warn once,
    naming the motions and how to pin them, and the exported flange is indeed off the truth by
    millimetres in the first case; a cable at the flange centre with a known port pins
    everything and they say nothing."""
    capture, plain = tmp_path / "capture", tmp_path / "plain"
    assert main(["simulate", str(SCENARIOS / "eyelet_irb120.toml"), "--out", str(capture)]) == 0
    assert main(["simulate", str(SCENARIOS / "geometric_irb120.toml"), "--out", str(plain)]) == 0
    results = {name: tmp_path / f"{name}.json" for name in ("estimated", "measured", "centre")}
    assert main(["calibrate", str(capture / "capture.toml"), "--json",
                 str(results["estimated"])]) == 0
    assert main(["calibrate", str(capture / "measurements.csv"), "--port", "600,-400,100",
                 "--attachment", "25,-15,40", "--json", str(results["measured"])]) == 0
    assert main(["calibrate", str(plain / "capture.toml"), "--json", str(results["centre"])]) == 0
    capsys.readouterr()
    expected = {"estimated": ("shift of the flange along its own x axis",
                              "--attachment X,Y,Z without --estimate-attachment"),
                "measured": ("(it turns about the measured point)",
                             "a second measured point on the tool"),
                "centre": None}
    for name, result in results.items():
        poses = (plain if name == "centre" else capture) / "measurements.csv"
        for argv in (["export", str(result), "--format", "dh", "--out",
                      str(tmp_path / f"{name}.toml")],
                     ["predict", "--identified", str(result), "--joints", str(poses), "--out",
                      str(tmp_path / f"{name}.csv")],
                     ["compensate", "--identified", str(result), "--joints", str(poses),
                      "--out", str(tmp_path / f"{name}_program.csv")]):
            assert main(argv) == 0
            err = capsys.readouterr().err
            # The directions held at the nominal (α6, θ6…) reach what carries frames.
            held = int(argv[0] != "predict")
            assert err.count("held at the nominal") == held, (name, argv[0], err)
            if expected[name] is None:
                assert err.count("twin: warning:") == held, (name, argv[0], err)
            else:
                assert err.count("twin: warning:") == 1 + held, (name, argv[0], err)
                assert all(text in err for text in expected[name]), (name, argv[0], err)
    sim = _simulate("eyelet_irb120")
    q = _workspace(sim)
    off_mm = {name: 1e3 * rms_distance(
        load_robot(tmp_path / f"{name}.toml").flange_positions(q),
        sim.true_robot.flange_positions(q)) for name in ("estimated", "measured")}
    assert off_mm["estimated"] > 1.0 > off_mm["measured"], off_mm
