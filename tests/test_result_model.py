"""A result file rebuilds the model it was identified with: kind, groups, rig and unknowns."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from twin.calibration.pipeline import calibrate
from twin.calibration.settings import CalibrationSettings
from twin.dataset import Measurements
from twin.errors import InputError
from twin.io.identified import load_result
from twin.io.results import result_to_dict, write_json
from twin.kinds.point import point_measurements
from twin.robot import RobotModel


def test_result_rebuilds_the_identified_model(
    tmp_path: Path, irb120: RobotModel, measurements: Measurements, port_m: np.ndarray
) -> None:
    """Every unknown comes back to the rounding of the file (1e-6 mm, 1e-6 deg), with the
    groups, the rig and σ; the rebuilt model predicts the same residuals."""
    result = calibrate(irb120, measurements, port_m, settings=CalibrationSettings(estimate=('port',
                                                                                            'offset')))
    path = tmp_path / "result.json"
    write_json(path, result_to_dict(result))
    loaded = load_result(path, irb120)
    assert loaded.model.names == result.model.names and loaded.method == "lm"
    scale = np.where(result.model.is_length, 1e-9, np.deg2rad(1e-6))
    assert np.all(np.abs(loaded.x - result.solver.x) <= scale)
    np.testing.assert_allclose(loaded.model.rig.ports_m, result.model.rig.ports_m, atol=1e-9)
    # Twelve angles rounded to 1e-6 degree (1.7e-8 rad) at a lever of under a metre.
    np.testing.assert_allclose(loaded.model.residuals(loaded.x, measurements),
                               result.model.residuals(result.solver.x, measurements), atol=5e-8)
    parameters = json.loads(path.read_text())["unknowns"]["parameters"]
    assert parameters[0] == {**parameters[0], "name": "a1", "group": "dh", "unit": "mm"}
    assert parameters[-1]["name"] == "offset" and parameters[-1]["sigma"] > 0
    assert parameters[-11]["name"] == "alpha6" and parameters[-11]["sigma"] is None


@pytest.mark.slow
@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda d: d["unknowns"]["groups"].append("tilt"), "found unknown error group 'tilt'"),
        (lambda d: d["unknowns"]["parameters"].pop(), "found 27 unknowns"),
        (lambda d: d["unknowns"]["parameters"][0].update(value=7.0), "found a1 = 7 mm"),
        (lambda d: d["unknowns"]["parameters"][0].update(unit="inch"), "found the unit 'inch'"),
        (lambda d: d.pop("unknowns"), "found no 'unknowns'"),
    ],
)
def test_a_result_that_cannot_be_right_is_refused(
    tmp_path: Path, irb120: RobotModel, measurements: Measurements, port_m: np.ndarray,
    change, message: str,
) -> None:
    """Unknown groups, a missing unknown, a value beyond its bound, a foreign unit: one line."""
    result = calibrate(irb120, measurements, port_m, settings=CalibrationSettings(estimate=('port',
                                                                                            'offset')))
    document = result_to_dict(result)
    change(document)
    path = tmp_path / "result.json"
    write_json(path, document)
    with pytest.raises(InputError, match=message):
        load_result(path, irb120)


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["position", "point", "stations"])
def test_results_of_every_rig_rebuild_their_model(tmp_path: Path, irb120: RobotModel,
                                                  kind: str) -> None:
    """A tracker result keeps its tracker frame exactly (the rigid-fit start), a fixed-point
    result its points and distances, a stations result which ports were estimated: the
    rebuilt model predicts the same residuals."""
    from twin.calibration.setup import make_model
    from twin.geometry.rigid import transform
    from twin.rig import Distance, Rig
    from twin.robot import random_poses

    rng = np.random.default_rng(11)
    q = random_poses(irb120, 60, rng)
    attachment = np.array([0.02, -0.01, 0.05])
    if kind == "position":
        truth = Rig(attachment_m=attachment,
                    base_in_tracker=transform([1.5, 0.2, 0.3], [0.01, -0.02, 2.0]))
        data = make_model(irb120, truth, "position").measure(np.zeros(24), q)
        rig, estimate = Rig(), ("base", "attachment")
    elif kind == "point":
        points = irb120.flange_positions(q[:2])
        place = np.arange(60) % 2
        data = point_measurements(q, place, point_names=("a", "b"))
        rig = Rig(distances=(Distance("a", "b", float(np.linalg.norm(points[0] - points[1]))),))
        estimate = ("attachment",)
    else:
        ports = np.array([[0.6, -0.4, 0.1], [0.3, 0.6, 0.05]])
        rig = Rig(ports, ("front", "left"), estimated_ports=("left",))
        data = make_model(irb120, rig, "length").measure(np.zeros(24), q, port=np.arange(60) % 2)
        estimate = ("port",)
    result = calibrate(irb120, data, rig=rig, settings=CalibrationSettings(estimate=estimate))
    path = tmp_path / "result.json"
    write_json(path, result_to_dict(result))
    loaded = load_result(path, irb120)
    assert loaded.model.names == result.model.names
    np.testing.assert_array_equal(loaded.model.rig.base_in_tracker,
                                  result.model.rig.base_in_tracker)
    assert loaded.model.rig.estimated_ports == result.model.rig.estimated_ports
    assert loaded.model.rig.point_names == result.model.rig.point_names
    np.testing.assert_allclose(loaded.model.residuals(loaded.x, data),
                               result.model.residuals(result.solver.x, data), atol=2e-7)
