"""Touches of planes (twin.kinds.plane): residuals mean what the kind says, the analytic Jacobian
equals central differences (with known distances between parallel planes and known angles
between planes too), the planes start where the data put them, what planes cannot see is named,
what a known angle adds is measured, and the twin's truth is recovered.

The recovery is held to the twin's ground truth (the probe's ball over held-out workspace poses
within 2× its Cramér–Rao bound, modulo what the data cannot see) and to an independent referee
computed here: scipy.optimize.least_squares on the same residual.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import least_squares

from tests.test_viz_rerun import column, read_rrd, scalars
from twin.analysis.gauge import gauge_free_rms, unobservable_motions
from twin.analysis.linearisation import linearise, model_jacobian
from twin.analysis.uncertainty import cramer_rao_rms
from twin.calibration.accuracy import rigid_truth, truth_errors
from twin.calibration.pipeline import calibrate
from twin.calibration.settings import CalibrationSettings
from twin.calibration.setup import make_model
from twin.cli import main
from twin.dataset import Measurements
from twin.errors import InputError
from twin.kinds.base import Noise
from twin.kinds.plane import ANGLE_WEIGHT, Plane, PlaneRig, PlaneSetup, plane_measurements
from twin.kinds.point import DISTANCE_WEIGHT
from twin.model import Model
from twin.rig import Angle, Distance, Rig
from twin.robot import RobotModel, random_poses
from twin.scenario import load_scenario
from twin.sim import simulate
from twin.study.trial import noise_sigma_m, true_unknowns
from twin.viz import entities

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "plane_irb120.toml"
NORMALS = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.6, 0.8, 0.0]])
OFFSETS_M = np.array([0.15, 0.25, 0.4])


def _numeric(function, x: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    steps = np.eye(x.size) * eps
    return np.moveaxis((function(x + steps) - function(x - steps)) / (2 * eps), 0, -1)


def _model(robot: RobotModel, distances: tuple[Distance, ...] = (),
           angles: tuple[Angle, ...] = ()) -> Model:
    rig = Rig(attachment_m=[0.01, 0.0, 0.08], distances=distances, angles=angles,
              part=PlaneRig(("a", "b", "c"), NORMALS, OFFSETS_M))
    return make_model(robot, rig, "plane", CalibrationSettings(estimate=("attachment",)))


@pytest.mark.parametrize(("distances", "angles"), [
    ((), ()), ((Distance("a", "b", 0.1),), ()),
    ((Distance("a", "b", 0.1),), (Angle("a", "c", 1.5), Angle("c", "b", 1.6)))])
def test_plane_jacobian_matches_differences(irb120: RobotModel, distances: tuple[Distance, ...],
                                            angles: tuple[Angle, ...]) -> None:
    """One row a touch, then one per known distance and one per known angle; ∂r/∂x of the D-H
    errors, the ball and the planes (two angles and an offset each) equals central
    differences, away from x = 0 too."""
    model = _model(irb120, distances, angles)
    q = random_poses(irb120, 12, np.random.default_rng(5))
    data = model.poses(q, plane=np.arange(12) % 3)
    x = np.random.default_rng(6).normal(scale=2e-3, size=model.n_params)
    r, jacobian = model.jacobian(x, data)
    assert r.shape == (12 + len(distances) + len(angles),)
    np.testing.assert_allclose(r, model.residuals(x, data), atol=1e-15)
    np.testing.assert_allclose(jacobian, _numeric(lambda xs: model.residuals(xs, data), x),
                               atol=1e-7)


def test_a_row_is_the_distance_of_the_point_from_its_plane(irb120: RobotModel) -> None:
    """r = n·p − d at the start planes; a plane moved by δd moves its rows by −δd, others not;
    a known distance's row is w(|d_a − d_b| − D) for parallel planes."""
    model = _model(irb120, (Distance("a", "b", 0.12),))
    q = random_poses(irb120, 9, np.random.default_rng(7))
    data = model.poses(q, plane=np.arange(9) % 3)
    x = np.zeros(model.n_params)
    points = model.positions(x, data)
    r = model.residuals(x, data)
    expected = np.sum(NORMALS[np.arange(9) % 3] * points, axis=1) - OFFSETS_M[np.arange(9) % 3]
    np.testing.assert_allclose(r[:9], expected, atol=1e-15)
    assert r[9] == pytest.approx(DISTANCE_WEIGHT * (0.1 - 0.12))
    moved = x.copy()
    moved[model.slice("planes").start + 2] = 1e-3  # plane a's offset
    change = model.residuals(moved, data)[:9] - r[:9]
    np.testing.assert_allclose(change[np.arange(9) % 3 == 0], -1e-3, atol=1e-15)
    np.testing.assert_allclose(change[np.arange(9) % 3 != 0], 0.0, atol=1e-15)


def test_a_known_angles_row_is_the_angle_between_the_normals_less_the_told(
        irb120: RobotModel) -> None:
    """Planes a and c stand at 90°: told 89°, the angle's row (after the touches) is
    W (90° − 89°) in radians; turning c's normal by δn moves it by −W n_a·δn (the angle's
    derivative at 90°); an angle to a plane the data do not name is refused."""
    model = _model(irb120, angles=(Angle("a", "c", np.deg2rad(89.0)),))
    q = random_poses(irb120, 9, np.random.default_rng(7))
    data = model.poses(q, plane=np.arange(9) % 3)
    x = np.zeros(model.n_params)
    assert model.residuals(x, data)[9] == pytest.approx(ANGLE_WEIGHT * np.deg2rad(1.0))
    planes = model.slice("planes").start
    moved = x.copy()
    moved[planes + 6: planes + 8] = 1e-3  # c's two angles: e1 and e2 of c lie in its plane
    first_axis = np.cross(NORMALS[2], [1.0, 0.0, 0.0])
    first_axis /= np.linalg.norm(first_axis)
    second_axis = np.cross(NORMALS[2], first_axis)
    tilt = np.arctan(1e-3) * (first_axis + second_axis) @ NORMALS[0]
    assert model.residuals(moved, data)[9] - model.residuals(x, data)[9] == pytest.approx(
        -tilt, rel=1e-3)
    with pytest.raises(InputError, match="an angle to the plane 'd'"):
        Plane().prepare(irb120, Rig(angles=(Angle("a", "d", 1.0),)),
                        plane_measurements(q, np.arange(9) % 3, plane_names=("a", "b", "c")),
                        Noise(1e-5))


def test_the_planes_start_where_the_nominal_points_lie(irb120: RobotModel) -> None:
    """prepare fits each named plane to the nominal model's points of its rows: through their
    centre, normal to their least spread (the smallest eigenvector of their covariance, computed
    here); a plane touched twice, or a distance to a plane the data do not name, is refused."""
    q = random_poses(irb120, 30, np.random.default_rng(8))
    labels = np.arange(30) % 2
    data = plane_measurements(q, labels, plane_names=("low", "high"))
    rig, _ = Plane().prepare(irb120, Rig(), data, Noise(1e-5))
    part = rig.part
    assert isinstance(part, PlaneRig) and part.names == ("low", "high")
    points = irb120.flange_positions(q)
    for j in range(2):
        on = points[labels == j]
        smallest = np.linalg.eigh(np.cov(on.T))[1][:, 0]
        assert abs(smallest @ part.normals[j]) == pytest.approx(1.0, abs=1e-9)
        assert part.normals[j] @ on.mean(axis=0) == pytest.approx(part.offsets_m[j], abs=1e-12)
    with pytest.raises(InputError, match="at least 3 touches of each plane"):
        Plane().prepare(irb120, Rig(), plane_measurements(q[:4], [0, 0, 1, 1]), Noise(1e-5))
    with pytest.raises(InputError, match="a distance to the plane 'side'"):
        Plane().prepare(irb120, Rig(distances=(Distance("low", "side", 0.1),)), data,
                        Noise(1e-5))


def _referee(model: Model, train: Measurements) -> np.ndarray:
    """scipy's least_squares on the same training residuals, from the same start."""
    return np.asarray(least_squares(lambda x: model.residuals(x, train),
                                    np.zeros(model.n_params), bounds=model.bounds(),
                                    x_scale="jac", xtol=1e-12, ftol=1e-12, gtol=1e-12).x)


@pytest.mark.slow
def test_planes_recover_the_ball_within_twice_the_bound() -> None:
    """Four faces, the block's height told: the ball's predicted position over 400 held-out
    workspace poses, modulo the turn about and shift along joint 1's axis the faces cannot
    see, is within 2× its Cramér–Rao bound of the twin's truth; scipy's least_squares on the
    same residual predicts the same modulo that placement; the gauge names it."""
    sim = simulate(load_scenario(SCENARIO))
    result = calibrate(sim.robot, sim.measurements, rig=sim.rig_told, method="lm",
                       settings=sim.scenario.calibration)
    model = result.model
    q = random_poses(sim.robot, 400, np.random.default_rng(2024))
    train = sim.measurements.subset(result.train_rows)
    x_true = true_unknowns(sim, model)
    sigma = noise_sigma_m(sim, model.jacobian(x_true, train)[1])
    errors = truth_errors(result, *rigid_truth(sim.true_robot, sim.rig.attachment_m, q), q)
    bound = cramer_rao_rms(model, x_true, train, sigma, q)[1]
    assert errors.point_gauge_free_m < 2 * bound, (errors, bound)
    assert result.gauge is not None
    names = result.gauge.names
    assert "rotation about joint 1's axis" in names and "shift along joint 1's axis" in names
    referee = _referee(model, train)
    assert result.identified_identifiability is not None
    null = result.identified_identifiability.null_space
    truth_points = rigid_truth(sim.true_robot, sim.rig.attachment_m, q)[1]
    assert gauge_free_rms(unobservable_motions(model, referee, null, q, measured=True),
                          truth_points) < 2 * bound


@pytest.mark.slow
def test_without_a_known_distance_the_scale_is_unseen() -> None:
    """The same faces, no height told: the kind gives the identifiability a common scale
    (every length, the ball and the faces' offsets) as a known gauge, and the result names
    it among the motions the data cannot see; with the height told it is seen."""
    sim = simulate(load_scenario(SCENARIO))
    settings = sim.scenario.calibration
    loose = calibrate(sim.robot, sim.measurements, rig=Rig(attachment_m=sim.rig_told.attachment_m),
                      method="lm", settings=settings)
    assert loose.model.symmetries(loose.solver.x).shape[1] == 1
    # The linearisation the checks read is the identifiable Jacobian, not the model's own.
    train = sim.measurements.subset(loose.train_rows)
    own = model_jacobian(loose.model, loose.solver.x, train)[1]
    identifiable = loose.model.identifiable_jacobian(loose.solver.x, train)[1]
    np.testing.assert_array_equal(linearise(loose.model, loose.solver.x, train).jacobian,
                                  identifiable)
    assert np.max(np.abs(own - identifiable)) > 0
    assert loose.gauge is not None and "scale about the base origin" in loose.gauge.names
    told = calibrate(sim.robot, sim.measurements, rig=sim.rig_told, method="lm",
                     settings=settings)
    assert told.model.symmetries(told.solver.x).shape[1] == 0
    assert told.gauge is not None and "scale about the base origin" not in told.gauge.names


@pytest.mark.slow
def test_known_angles_between_the_faces_sharpen_the_ball() -> None:
    """The scenario's faces with their five right angles told as well as the block's height:
    the ball's Cramér–Rao bound over held-out workspace poses (modulo joint 1's placement) is
    under half of the height's alone (0.051 against 0.155 mm when measured), and the fit is
    within 2× it of the twin's truth."""
    scenario = load_scenario(SCENARIO)
    setup = scenario.instrument.setup
    assert isinstance(setup, PlaneSetup)
    angles = replace(setup, tell_angles=True).angles
    assert len(angles) == 5 and all(a.angle_rad == pytest.approx(np.pi / 2) for a in angles)
    sim = simulate(scenario)
    q = random_poses(sim.robot, 400, np.random.default_rng(2024))
    bounds, errors = [], []
    for rig in (sim.rig_told, replace(sim.rig_told, angles=angles)):
        result = calibrate(sim.robot, sim.measurements, rig=rig, method="lm",
                           settings=sim.scenario.calibration)
        model, train = result.model, sim.measurements.subset(result.train_rows)
        x_true = true_unknowns(sim, model)
        sigma = noise_sigma_m(sim, model.jacobian(x_true, train)[1])
        bounds.append(cramer_rao_rms(model, x_true, train, sigma, q)[1])
        errors.append(truth_errors(result, *rigid_truth(sim.true_robot, sim.rig.attachment_m,
                                                         q), q).point_gauge_free_m)
    assert bounds[1] < 0.5 * bounds[0], bounds
    assert errors[1] < 2 * bounds[1], (errors, bounds)


@pytest.mark.slow
def test_planes_run_through_the_command_line(tmp_path: Path) -> None:
    """twin simulate → calibrate (with a Rerun recording) → predict on the plane scenario: the
    report names each identified face, the result keeps the faces the calibration started
    from, and the prediction gives the ball's position."""
    out = tmp_path / "plane"
    assert main(["simulate", str(SCENARIO), "--out", str(out)]) == 0
    assert (out / "measurements.csv").read_text().splitlines()[0] == "q1,q2,q3,q4,q5,q6,plane"
    assert main(["calibrate", str(out / "capture.toml"), "--json", str(out / "result.json"),
                 "--rerun-save", str(out / "calibrate.rrd")]) == 0
    batches = read_rrd(out / "calibrate.rrd")
    assert len(column(batches, entities.MEASURED, entities.POSE_TIMELINE)) == 80
    assert entities.world("planes") in batches
    assert scalars(batches, entities.residuals_after("lm")).shape == (80,)
    part = json.loads((out / "result.json").read_text())["unknowns"]["rig"]["plane"]
    assert part["names"] == ["plane1", "plane2", "plane3", "plane4"]
    assert main(["predict", "--identified", str(out / "result.json"), "--joints",
                 str(out / "measurements.csv"), "--out", str(out / "predicted.csv")]) == 0
    header = (out / "predicted.csv").read_text().splitlines()[0].split(",")
    assert header[-3:] == ["x", "y", "z"]


@pytest.mark.slow
def test_a_scenarios_angles_reach_the_calibration_through_the_capture(tmp_path: Path) -> None:
    """[planes] angles = true: twin simulate writes the five right angles of the faces into the
    capture's [rig] angles, calibrate reads them back and the result lists them (degrees)."""
    text = SCENARIO.read_text().replace("distances = true", "distances = true\nangles = true")
    text = text.replace('"../models/irb120.toml"',
                        json.dumps(str(SCENARIO.parents[1] / "models" / "irb120.toml")))
    scenario = tmp_path / "angles.toml"
    scenario.write_text(text)
    out = tmp_path / "out"
    assert main(["simulate", str(scenario), "--out", str(out)]) == 0
    assert 'angles = ["plane1,plane3=90.0", ' in (out / "capture.toml").read_text()
    assert main(["calibrate", str(out / "capture.toml"), "--json",
                 str(out / "result.json")]) == 0
    rig = json.loads((out / "result.json").read_text())["unknowns"]["rig"]
    assert [a["planes"] for a in rig["angles"]] == [
        ["plane1", "plane3"], ["plane1", "plane4"], ["plane2", "plane3"], ["plane2", "plane4"],
        ["plane3", "plane4"]]
    assert all(a["angle_deg"] == pytest.approx(90.0) for a in rig["angles"])


def test_a_planes_axes_are_made_once_read_only_and_span_it() -> None:
    """The axes e1, e2 every evaluation reads: unit, in the plane, e1 × e2 = n; made once for
    the rig's planes and read-only, so that no evaluation can move them for the next."""
    normals = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8], [0.95, 0.1, np.sqrt(1 - 0.9125)]])
    part = PlaneRig(("floor", "slope", "wall"), normals, np.zeros(3))
    first, second = part.axes
    assert part.axes[0] is first and part.axes[1] is second
    for axis in (first, second):
        np.testing.assert_allclose(np.linalg.norm(axis, axis=1), 1.0, atol=1e-15)
        np.testing.assert_allclose(np.sum(axis * normals, axis=1), 0.0, atol=1e-15)
    np.testing.assert_allclose(np.cross(first, second), normals, atol=1e-15)
    with pytest.raises(ValueError, match="read-only"):
        first[0, 0] = 1.0
