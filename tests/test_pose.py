"""6-D poses (twin.kinds.pose): residuals mean what the kind says, the analytic Jacobian equals
central differences for every group, files round-trip, and the twin's poses are recovered.

The recovery is held to the twin's ground truth — α6 and θ6, which no point on the flange axis
sees, within 2× their Cramér–Rao bound over trials, the tool frame over held-out workspace
poses within 2× its bound — and to an independent referee computed here:
scipy.optimize.least_squares on the same residual (its own trust-region method and
finite-difference Jacobian).
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from tests.test_viz_rerun import column, read_rrd, scalars
from twin.analysis.uncertainty import cramer_rao_covariance, rms_distance
from twin.calibration.pipeline import calibrate
from twin.calibration.settings import CalibrationSettings
from twin.calibration.setup import make_model
from twin.cli import main
from twin.dataset import Measurements
from twin.errors import InputError
from twin.geometry.rigid import log_rotation, transform
from twin.io.measurements import load_measurements, write_measurements
from twin.io.robot_file import load_robot
from twin.kinds.base import Noise
from twin.kinds.pose import ROTATION, PoseRig, pose_measurements
from twin.model import Model
from twin.rig import Rig
from twin.robot import RobotModel, random_poses
from twin.scenario import load_scenario
from twin.sim import Simulation, simulate
from twin.study.trial import noise_sigma_m, true_unknowns
from twin.viz import entities

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "pose_irb120.toml"
TORSO = Path(__file__).resolve().parents[1] / "models" / "fr3_torso" / "fr3_torso.urdf"
FRAME = transform([1.6, 0.3, -0.2], [0.05, -0.1, 2.8])
TOOL = Rotation.from_rotvec([0.3, -0.2, 0.9]).as_matrix()


def _numeric(function, x: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    steps = np.eye(x.size) * eps
    return np.moveaxis((function(x + steps) - function(x - steps)) / (2 * eps), 0, -1)


@pytest.fixture(scope="module")
def q_rad(irb120: RobotModel) -> np.ndarray:
    return random_poses(irb120, 10, np.random.default_rng(61))


def _model(robot: RobotModel, estimate: tuple[str, ...]) -> Model:
    rig = Rig(attachment_m=[0.02, -0.01, 0.06], base_in_tracker=FRAME,
              part=PoseRig(TOOL, 0.05))
    return make_model(robot, rig, "pose", CalibrationSettings(estimate=estimate))


@pytest.mark.parametrize("estimate", [(), ("base",), ("tool",), ("base", "tool")])
def test_pose_jacobian_matches_differences(irb120: RobotModel, q_rad: np.ndarray,
                                           estimate: tuple[str, ...]) -> None:
    """Six rows a pose; ∂r/∂x of the D-H errors, the tool frame (origin and rotation) and the
    instrument's frame equals central differences, away from x = 0 too (the orientation rows'
    J_l⁻¹ and the tool's J_r are not the identity there)."""
    model = _model(irb120, estimate)
    rng = np.random.default_rng(3)
    truth = rng.normal(scale=2e-3, size=model.n_params)
    data = model.measure(truth, q_rad)
    assert model.residuals(truth, data).shape == (6 * len(q_rad),)
    x = truth + rng.normal(scale=5e-3, size=model.n_params)
    r, jacobian = model.jacobian(x, data)
    np.testing.assert_allclose(r, model.residuals(x, data), atol=1e-14)
    np.testing.assert_allclose(jacobian, _numeric(lambda xs: model.residuals(xs, data), x),
                               atol=1e-7)


def test_a_reading_is_the_tool_frame_in_the_instrument_frame(irb120: RobotModel,
                                                            q_rad: np.ndarray) -> None:
    """The model reads FRAME · flange pose · tool: position of the origin, and orientation;
    an orientation 1° off gives w·1° (in m) on its rows and nothing on the position's."""
    model = _model(irb120, ())
    data = model.measure(np.zeros(model.n_params), q_rad)
    flange = irb120.flange_transforms(q_rad)
    tool = np.eye(4)
    tool[:3, :3], tool[:3, 3] = TOOL, [0.02, -0.01, 0.06]
    expected = FRAME @ flange @ tool
    np.testing.assert_allclose(data.value("position_m"), expected[:, :3, 3], atol=1e-14)
    np.testing.assert_allclose(data.value(ROTATION), expected[:, :3, :3], atol=1e-14)
    turned = data.value(ROTATION) @ Rotation.from_rotvec([0.0, 0.0, np.deg2rad(1.0)]
                                                         ).as_matrix()
    off = replace(data, values={**data.values, ROTATION: turned})
    rows = model.residuals(np.zeros(model.n_params), off).reshape(-1, 6)
    np.testing.assert_allclose(rows[:, :3], 0.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(rows[:, 3:], axis=1), 0.05 * np.deg2rad(1.0),
                               rtol=1e-9)


def test_pose_files_round_trip(tmp_path: Path, irb120: RobotModel, q_rad: np.ndarray) -> None:
    """x,y,z (mm) and qw,qx,qy,qz are written and read back to the same poses; a quaternion
    that is not a unit one is refused naming its line."""
    model = _model(irb120, ())
    data = model.measure(np.zeros(model.n_params), q_rad)
    path = tmp_path / "poses.csv"
    write_measurements(path, data)
    assert path.read_text().splitlines()[0] == "q1,q2,q3,q4,q5,q6,x,y,z,qw,qx,qy,qz"
    back = load_measurements(path, irb120)
    assert back.kind == "pose"
    np.testing.assert_allclose(back.value("position_m"), data.value("position_m"), atol=1e-12)
    np.testing.assert_allclose(back.value(ROTATION), data.value(ROTATION), atol=1e-12)
    lines = path.read_text().splitlines()
    fields = lines[2].split(",")
    fields[9] = "0.5"
    path.write_text("\n".join([*lines[:2], ",".join(fields), *lines[3:]]) + "\n")
    with pytest.raises(InputError, match=r"line 3: found a quaternion of norm"):
        load_measurements(path, irb120)


def test_positions_alone_do_not_make_a_pose_file(tmp_path: Path, irb120: RobotModel) -> None:
    """x,y,z with a part of a quaternion is refused; x,y,z alone is a tracker's file."""
    q = random_poses(irb120, 3, np.random.default_rng(1))
    path = tmp_path / "m.csv"
    rows = [",".join(f"{v:.6f}" for v in np.degrees(row)) + ",1,2,3,1" for row in q]
    path.write_text("q1,q2,q3,q4,q5,q6,x,y,z,qw\n" + "\n".join(rows) + "\n")
    with pytest.raises(InputError, match="exactly one of"):
        load_measurements(path, irb120)


def _simulate(seed: int | None = None) -> Simulation:
    return simulate(load_scenario(SCENARIO), seed)


def _settings(sim: Simulation, estimate: tuple[str, ...]) -> CalibrationSettings:
    return replace(sim.scenario.calibration, estimate=estimate)


def _referee(model: Model, train: Measurements) -> np.ndarray:
    """scipy's least_squares on the same training residuals, from the same start. Its
    tolerances are 1e-10: at 1e-12, with the tool frame estimated, it wandered 276 steps (30 s)
    along the directions the data cannot see before its gradient test fired, to predict the
    readings no better (4e-9 m against 1e-10 m after 9 steps)."""
    return np.asarray(least_squares(lambda x: model.residuals(x, train),
                                    np.zeros(model.n_params), bounds=model.bounds(),
                                    x_scale="jac", xtol=1e-10, ftol=1e-10, gtol=1e-10).x)


def _bound_sigma(model: Model, x_true: np.ndarray, train: Measurements, sigma_m: float
                 ) -> np.ndarray:
    """The Cramér–Rao σ of every unknown the training poses see (0 for those held), SI."""
    return np.sqrt(np.diag(cramer_rao_covariance(model, x_true, train, sigma_m)))


@pytest.mark.slow
def test_poses_identify_alpha6_and_theta6_within_twice_their_bound() -> None:
    """With the tool frame known and the instrument's frame estimated, the identifiability
    says orientations see α6 and θ6 (a point on the flange cannot), and over 8 trials their
    RMS error against the twin's truth is within 2× the Cramér–Rao σ; scipy's least_squares
    on the same residual lands on the same α6 and θ6."""
    errors, bounds = [], []
    for seed in range(8):
        sim = _simulate(100 + seed)
        result = calibrate(sim.robot, sim.measurements, rig=sim.rig_told, method="lm",
                           settings=_settings(sim, ("base",)), seed=seed)
        model = result.model
        names = [model.names.index(name) for name in ("alpha6", "theta6")]
        assert result.identifiability is not None
        assert {"alpha6", "theta6"} <= set(result.identifiability.beyond_points)
        null = result.identifiability.null_space
        assert np.max(np.abs(null[names]), initial=0.0) < 1e-9  # each identified alone
        train = sim.measurements.subset(result.train_rows)
        x_true = true_unknowns(sim, model)
        sigma = noise_sigma_m(sim, model.jacobian(x_true, train)[1])
        errors.append(result.solver.x[names] - x_true[names])
        bounds.append(_bound_sigma(model, x_true, train, sigma)[names])
        if seed == 0:
            referee = _referee(model, train)
            np.testing.assert_allclose(referee[names], result.solver.x[names],
                                       atol=0.1 * float(np.min(bounds[0])))
    rms = np.sqrt(np.mean(np.square(errors), axis=0))
    bound = np.sqrt(np.mean(np.square(bounds), axis=0))
    assert np.all(rms < 2 * bound), (rms, bound)
    assert np.all(bound < np.deg2rad(0.01))  # a few arc-seconds: they are seen, not guessed


@pytest.mark.slow
def test_the_tool_frame_is_recovered_over_held_out_poses() -> None:
    """With the tool frame estimated (6-D) as well, what the instrument would read of the tool
    frame at 300 held-out workspace poses — its origin and its orientation, in the instrument's
    frame, where the turn about and shift along joint 1's axis the data cannot see are the
    frame's — is within 2× its Cramér–Rao bound of the twin's truth; scipy's least_squares on
    the same residual predicts the same; the identifiability says α6 and θ6 now trade with the
    tool's rotation."""
    sim = _simulate()
    result = calibrate(sim.robot, sim.measurements, rig=sim.rig_told, method="lm",
                       settings=_settings(sim, ("base", "tool")))
    model = result.model
    assert result.identifiability is not None
    unseen = " ".join(result.identifiability.unidentifiable)
    assert "tool_rx" in unseen and "alpha6" in unseen, unseen
    q = random_poses(sim.robot, 300, np.random.default_rng(2024))
    train = sim.measurements.subset(result.train_rows)
    x_true = true_unknowns(sim, model)
    sigma = noise_sigma_m(sim, model.jacobian(x_true, train)[1])
    truth = Model(sim.true_robot, sim.rig, model.kind, ()).measure(np.zeros(0), q)
    found = model.measure(result.solver.x, q)
    position, angle = _pose_errors(found, truth)
    position_bound, angle_bound = _pose_bounds(model, x_true, train, sigma, q)
    assert position < 2 * position_bound, (position, position_bound)
    assert angle < 2 * angle_bound, (angle, angle_bound)
    referee = _pose_errors(model.measure(_referee(model, train), q), found)
    assert referee[0] < 0.2 * position_bound and referee[1] < 0.2 * angle_bound, referee


def _pose_errors(found: Measurements, truth: Measurements) -> tuple[float, float]:
    """RMS distance (m) and RMS angle (rad) between two sets of instrument readings."""
    turn = log_rotation(np.swapaxes(truth.value(ROTATION), 1, 2) @ found.value(ROTATION))
    return (rms_distance(found.value("position_m"), truth.value("position_m")),
            float(np.sqrt(np.mean(np.sum(turn**2, axis=1)))))


def _pose_bounds(model: Model, x_true: np.ndarray, train: Measurements, sigma_m: float,
                 q: np.ndarray) -> tuple[float, float]:
    """The Cramér–Rao bounds (m, rad) of the RMS distance and angle of the instrument's
    readings of the tool frame at poses q: the rows' Jacobian there, the covariance of the
    training poses."""
    covariance = cramer_rao_covariance(model, x_true, train, sigma_m)
    rows = model.jacobian(x_true, model.measure(x_true, q))[1].reshape(len(q), 6, -1)
    weight = model.rig.part.weight_m_per_rad  # type: ignore[union-attr]
    variance = [np.einsum("mij,jk,mik->m", part, covariance, part)
                for part in (rows[:, :3], rows[:, 3:] / weight)]
    return float(np.sqrt(np.mean(variance[0]))), float(np.sqrt(np.mean(variance[1])))


@pytest.mark.slow
def test_pose_runs_through_the_command_line(tmp_path: Path) -> None:
    """twin simulate → calibrate (with a Rerun recording) → predict on the pose scenario: the
    report says what orientations see, the result keeps the tool rotation and the weight, and
    the prediction gives the tool frame in the base and the instrument's frames, the latter
    within the noise of the readings."""
    out = tmp_path / "pose"
    assert main(["simulate", str(SCENARIO), "--out", str(out)]) == 0
    assert main(["calibrate", str(out / "capture.toml"), "--json", str(out / "result.json"),
                 "--rerun-save", str(out / "calibrate.rrd")]) == 0
    batches = read_rrd(out / "calibrate.rrd")
    poses = len((out / "measurements.csv").read_text().splitlines()) - 1
    assert len(column(batches, entities.MEASURED, entities.POSE_TIMELINE)) == poses
    for axis in "xyz":  # the tool frame's axes as read, a segment per pose
        assert len(column(batches, entities.world(f"measured_axes/{axis}"),
                          entities.POSE_TIMELINE)) == poses
    assert scalars(batches, entities.residuals_after("lm")).shape == (poses,)
    document = json.loads((out / "result.json").read_text())
    part = document["unknowns"]["rig"]["pose"]
    assert len(part["tool_rotation"]) == 9 and part["weight_m_per_rad"] > 0
    assert main(["predict", "--identified", str(out / "result.json"), "--joints",
                 str(out / "measurements.csv"), "--out", str(out / "predicted.csv")]) == 0
    header = (out / "predicted.csv").read_text().splitlines()[0].split(",")
    assert header[12:] == ["x", "y", "z", "qw", "qx", "qy", "qz", "instrument_x", "instrument_y",
                          "instrument_z", "instrument_qw", "instrument_qx", "instrument_qy",
                          "instrument_qz"]
    table = np.genfromtxt(out / "predicted.csv", delimiter=",", names=True)
    read = load_measurements(out / "measurements.csv")
    predicted = np.stack([table[f"instrument_{a}"] for a in "xyz"], axis=1)
    scatter = rms_distance(predicted, 1e3 * read.value("position_m")) / np.sqrt(3)
    sigma_mm = load_scenario(SCENARIO).instrument.setup.sigma_m[0] * 1e3  # type: ignore
    assert scatter < 3 * sigma_mm, scatter
    quaternion = np.stack([table[f"instrument_q{a}"] for a in "wxyz"], axis=1)
    turned = Rotation.from_quat(quaternion, scalar_first=True).as_matrix()
    angle = np.linalg.norm(log_rotation(np.swapaxes(read.value(ROTATION), 1, 2) @ turned),
                           axis=1)
    sigma_rad = load_scenario(SCENARIO).instrument.setup.sigma_rad[0]  # type: ignore[attr-defined]
    assert np.sqrt(np.mean(angle**2)) < 3 * np.sqrt(3) * sigma_rad


def test_a_noise_weighs_the_orientation_rows(irb120: RobotModel, q_rad: np.ndarray) -> None:
    """prepare sets w = σ / σ_θ; without σ_θ, 0.01° stands for it."""
    kind = make_model(irb120, Rig(), "pose").kind
    data = pose_measurements(q_rad, np.zeros((len(q_rad), 3)),
                             np.broadcast_to(np.eye(3), (len(q_rad), 3, 3)))
    rig, _ = kind.prepare(irb120, Rig(), data, Noise(1e-5, np.deg2rad(0.02)))
    assert isinstance(rig.part, PoseRig)
    assert rig.part.weight_m_per_rad == pytest.approx(1e-5 / np.deg2rad(0.02))
    rig, _ = kind.prepare(irb120, Rig(), data, Noise(2e-5))
    assert rig.part.weight_m_per_rad == pytest.approx(2e-5 / np.deg2rad(0.01))  # type: ignore


def test_another_tools_pose_csv_is_imported_in_its_units(tmp_path: Path, irb120: RobotModel,
                                                         q_rad: np.ndarray) -> None:
    """A CSV in radians and metres with a quaternion: the positions are scaled, the quaternion
    is not (it has no unit)."""
    from twin.io.importers.csv_files import read_csv_files

    model = _model(irb120, ())
    data = model.measure(np.zeros(model.n_params), q_rad)
    quaternion = Rotation.from_matrix(np.array(data.value(ROTATION))).as_quat(scalar_first=True)
    rows = [",".join(repr(float(v)) for v in [*q, *p, *w]) for q, p, w in
            zip(q_rad, data.value("position_m"), quaternion, strict=True)]
    path = tmp_path / "poses.csv"
    path.write_text("q1,q2,q3,q4,q5,q6,x,y,z,qw,qx,qy,qz\n" + "\n".join(rows) + "\n")
    imported = read_csv_files([path], irb120, angle_unit="rad", length_unit="m").measurements
    assert imported.kind == "pose"
    np.testing.assert_allclose(imported.value("position_m"), data.value("position_m"),
                               atol=1e-12)
    np.testing.assert_allclose(imported.value(ROTATION), data.value(ROTATION), atol=1e-12)


@pytest.mark.parametrize("torso", [False, True], ids=["irb120", "fr3 on a torso lift"])
def test_joint_jacobian_of_poses_matches_differences(irb120: RobotModel, q_rad: np.ndarray,
                                                     torso: bool) -> None:
    """∂r/∂q (errors in the recorded angles) of position and orientation rows equals central
    differences, and ∂r/∂x too: on a prismatic lift the slide turns no orientation row."""
    robot = load_robot(TORSO) if torso else irb120
    q_rad = random_poses(robot, 12, np.random.default_rng(3)) if torso else q_rad
    model = _model(robot, ("base", "tool"))
    x = np.random.default_rng(9).normal(scale=2e-3, size=model.n_params)
    data = model.measure(x, q_rad + 1e-3)

    def shifted(step: np.ndarray) -> np.ndarray:
        return model.residuals(x, replace(data, q_rad=q_rad + step))

    at = replace(data, q_rad=q_rad)
    joints = model.joint_jacobian(x, at)
    for j in range(robot.n_joints):
        step = np.zeros_like(q_rad)
        step[:, j] = 1e-6
        numeric = (shifted(step) - shifted(-step)) / 2e-6
        np.testing.assert_allclose(joints[:, j], numeric, atol=1e-7)
    np.testing.assert_allclose(model.jacobian(x, at)[1], _numeric(
        lambda xs: model.residuals(xs, at), x), atol=1e-7)
