"""Tracker positions and fixed points as measurement kinds, with the rig's new unknowns (the
attachment point, the tracker frame, the fixed points, a subset of estimated ports): residuals
mean what their kind says, and every analytic Jacobian equals central differences."""

from __future__ import annotations

import numpy as np
import pytest

from twin.calibration.settings import CalibrationSettings
from twin.calibration.setup import make_model
from twin.dataset import Measurements
from twin.geometry.rigid import transform
from twin.kinds.point import DISTANCE_WEIGHT
from twin.model import Model
from twin.rig import Distance, Rig
from twin.robot import RobotModel, random_poses

EYELET_M = np.array([0.025, -0.015, 0.04])
BASE_IN_TRACKER = transform([1.2, -0.3, 0.4], [0.1, -0.2, 2.5])


def _numeric(function, x: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    steps = np.eye(x.size) * eps
    return np.moveaxis((function(x + steps) - function(x - steps)) / (2 * eps), 0, -1)


def _check_jacobian(model: Model, data: Measurements, seed: int) -> None:
    x = np.random.default_rng(seed).normal(scale=1e-3, size=model.n_params)
    r, jacobian = model.jacobian(x, data)
    np.testing.assert_allclose(r, model.residuals(x, data), atol=1e-15)
    np.testing.assert_allclose(jacobian, _numeric(lambda xs: model.residuals(xs, data), x),
                               atol=1e-8)


@pytest.fixture(scope="module")
def q_rad(irb120: RobotModel) -> np.ndarray:
    return random_poses(irb120, 12, np.random.default_rng(21))


@pytest.mark.parametrize("estimate", [(), ("attachment",), ("base",), ("attachment", "base")])
def test_position_jacobian_matches_differences(irb120: RobotModel, q_rad: np.ndarray,
                                               estimate: tuple[str, ...]) -> None:
    """Tracker rows: ∂r/∂x of the D-H errors, the target point and the tracker frame."""
    rig = Rig(attachment_m=EYELET_M, base_in_tracker=BASE_IN_TRACKER)
    model = make_model(irb120, rig, "position", settings=CalibrationSettings(estimate=estimate))
    data = model.measure(np.zeros(model.n_params), q_rad)
    assert model.kind.rows_per_pose == 3 and model.residuals(np.zeros(model.n_params),
                                                             data).shape == (36,)
    _check_jacobian(model, data, 1)


def test_position_reads_the_target_in_the_tracker_frame(irb120: RobotModel,
                                                        q_rad: np.ndarray) -> None:
    """A reading is base_in_tracker · (flange pose · target), nothing else."""
    rig = Rig(attachment_m=EYELET_M, base_in_tracker=BASE_IN_TRACKER)
    model = make_model(irb120, rig, "position")
    data = model.measure(np.zeros(model.n_params), q_rad)
    flange = irb120.flange_transforms(q_rad)
    target = flange[:, :3, :3] @ EYELET_M + flange[:, :3, 3]
    expected = target @ BASE_IN_TRACKER[:3, :3].T + BASE_IN_TRACKER[:3, 3]
    np.testing.assert_allclose(data.value("position_m"), expected, atol=1e-14)


@pytest.mark.parametrize("distances", [(), (Distance("a", "b", 0.05), Distance("b", "c", 0.1))])
def test_point_jacobian_matches_differences(irb120: RobotModel, q_rad: np.ndarray,
                                            distances: tuple[Distance, ...]) -> None:
    """Fixed-point rows and known-distance rows: ∂r/∂x of the D-H errors, the tool point and
    the fixed points."""
    points = np.array([[0.4, 0.0, 0.3], [0.45, 0.0, 0.3], [0.4, 0.1, 0.35]])
    rig = Rig(attachment_m=EYELET_M, point_names=("a", "b", "c"), points_m=points,
              distances=distances)
    model = make_model(irb120, rig, "point", settings=CalibrationSettings(estimate=("attachment",)))
    place = np.arange(len(q_rad)) % 3
    data = model.measure(np.zeros(model.n_params), q_rad, point=place)
    r = model.residuals(np.zeros(model.n_params), data)
    assert r.shape == (3 * len(q_rad) + len(distances),)
    positions = model.positions(np.zeros(model.n_params), data)
    np.testing.assert_allclose(r[: 3 * len(q_rad)], (positions - points[place]).ravel(),
                               atol=1e-15)
    expected = DISTANCE_WEIGHT * np.array([np.linalg.norm(points[0] - points[1]) - 0.05,
                                           np.linalg.norm(points[1] - points[2]) - 0.1])
    expected = expected[: len(distances)]
    np.testing.assert_allclose(r[3 * len(q_rad):], expected, atol=1e-15)
    _check_jacobian(model, data, 2)


def test_estimated_ports_are_a_subset(irb120: RobotModel, q_rad: np.ndarray) -> None:
    """With one of three ports measured, the port group corrects the other two only, and its
    Jacobian matches differences."""
    ports = np.array([[0.6, -0.4, 0.1], [0.5, 0.5, 0.0], [-0.3, 0.6, 0.2]])
    rig = Rig(ports, ("front", "left", "back"), EYELET_M, estimated_ports=("front", "back"))
    model = make_model(irb120, rig, settings=CalibrationSettings(estimate=("port",)))
    assert model.names[24:] == ("front_x", "front_y", "front_z", "back_x", "back_y", "back_z")
    data = model.measure(np.zeros(model.n_params), q_rad, port=np.arange(len(q_rad)) % 3)
    _check_jacobian(model, data, 3)
    x = np.zeros(model.n_params)
    x[model.slice("port")] = [0.01, 0, 0, 0, 0, 0.02]
    moved = model.residuals(x, data) - model.residuals(np.zeros(model.n_params), data)
    np.testing.assert_array_equal(moved[data.index("port") == 1], 0.0)
    assert np.all(np.abs(moved[data.index("port") != 1]) > 0)


def test_measured_point_jacobian(irb120: RobotModel, q_rad: np.ndarray) -> None:
    """∂(measured point)/∂x equals differences: the table and the attachment move it, the
    tracker frame does not."""
    rig = Rig(attachment_m=EYELET_M, base_in_tracker=BASE_IN_TRACKER)
    model = make_model(irb120, rig, "position", settings=CalibrationSettings(estimate=("attachment",
                                                                                       "base")))
    data = model.poses(q_rad)
    x = np.random.default_rng(4).normal(scale=1e-3, size=model.n_params)
    jacobian = model.position_jacobian(x, data)
    np.testing.assert_allclose(jacobian, _numeric(lambda xs: model.positions(xs, data), x),
                               atol=1e-8)
    np.testing.assert_array_equal(jacobian[..., model.slice("base")], 0.0)
    np.testing.assert_array_equal(model.flange_jacobian(x, data)[..., model.slice("attachment")],
                                  0.0)


def test_batched_residuals_of_every_kind(irb120: RobotModel, q_rad: np.ndarray) -> None:
    """K candidates in one call equal K single calls, for tracker and fixed-point rows."""
    rig = Rig(attachment_m=EYELET_M, base_in_tracker=BASE_IN_TRACKER, point_names=("a", "b"),
              points_m=[[0.4, 0.0, 0.3], [0.45, 0.0, 0.3]],
              distances=(Distance("a", "b", 0.05),))
    for kind, estimate in (("position", ("attachment", "base")), ("point", ("attachment",))):
        model = make_model(irb120, rig, kind, settings=CalibrationSettings(estimate=estimate))
        data = model.poses(q_rad, point=np.arange(len(q_rad)) % 2)
        x = np.random.default_rng(5).normal(scale=1e-3, size=(4, model.n_params))
        batched = model.residuals(x, data)
        for k in range(4):
            np.testing.assert_allclose(batched[k], model.residuals(x[k], data), atol=1e-15)
