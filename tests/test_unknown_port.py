"""A port nobody measured (``--port unknown``): started by multilateration from the lengths and
searched without the told port's ±50 mm box, on the twin (seeded): the found port and the
flange against the twin's truth on what cable lengths can see, and against scipy's
least_squares on the same residual from the same start; poses that cannot place a port are
refused in one line."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import Refusals
from scipy.optimize import least_squares

from twin.analysis.gauge import gauge_free_rms, unobservable_motions
from twin.analysis.uncertainty import cramer_rao_rms
from twin.calibration.accuracy import rigid_truth, truth_errors
from twin.calibration.pipeline import calibrate
from twin.calibration.settings import CalibrationSettings
from twin.cli import main
from twin.io.measurements import write_measurements
from twin.kinds.length import length_measurements
from twin.robot import random_poses
from twin.scenario import load_scenario
from twin.sim import simulate
from twin.study.trial import noise_sigma_m, true_unknowns

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "unknown_port_irb120.toml"
GUESS_OFF_M = np.array([0.3, 0.0, 0.0])
"""How far the one guess anybody had is from the true port: 300 mm."""
PORT_SETTINGS = CalibrationSettings(estimate=("port",))


def _radius(port_m: np.ndarray) -> float:
    """The port's distance from joint 1's axis (the base z axis): what lengths see of it
    (a turn about that axis and a shift along it trade with δθ1 and δd1)."""
    return float(np.hypot(port_m[0], port_m[1]))


@pytest.mark.slow
def test_a_port_300_mm_from_any_guess_is_found() -> None:
    """Told only that the port is unknown (the guess 300 mm off is not used), the calibration
    starts it within 2 mm of the truth, finds its distance from joint 1's axis to 0.05 mm,
    and the flange modulo what lengths cannot see is within 2× its Cramér–Rao bound; scipy
    from the same start agrees to 0.2× the bound. Told the guess instead, ±50 mm around it
    cannot reach the port: a misfit."""
    sim = simulate(load_scenario(SCENARIO))
    truth = sim.rig.ports_m[0]
    guess = truth + GUESS_OFF_M
    unknown = replace(sim.rig_told, ports_m=guess[None], unknown_ports=("port",))
    result = calibrate(sim.robot, sim.measurements, rig=unknown, settings=PORT_SETTINGS)
    start = result.model.rig.ports_m[0]
    assert np.linalg.norm(start - truth) < 2e-3, start - truth
    assert abs(_radius(result.ports_m[0]) - _radius(truth)) < 5e-5
    assert result.misfit is not None and not result.misfit.misfit
    q = random_poses(sim.robot, 500, np.random.default_rng(2024))
    errors = truth_errors(result, *rigid_truth(sim.true_robot, sim.rig.attachment_m, q), q)
    model, train = result.model, sim.measurements.subset(result.train_rows)
    x_true = true_unknowns(sim, model)
    bound = cramer_rao_rms(model, x_true, train,
                           noise_sigma_m(sim, model.jacobian(x_true, train)[1]), q)[0]
    assert errors.flange_gauge_free_m < 2 * bound, (errors, bound)
    lower, upper = model.bounds()
    referee = least_squares(lambda x: model.residuals(x, train), np.zeros(model.n_params),
                            bounds=(lower, upper), x_scale="jac", xtol=1e-12, ftol=1e-12,
                            gtol=1e-12).x
    assert result.identified_identifiability is not None
    null = result.identified_identifiability.null_space
    assert gauge_free_rms(unobservable_motions(model, referee, null, q),
                          sim.true_robot.flange_positions(q)) < 2 * bound
    referee_port = start + model.block(referee, "port")
    assert abs(_radius(referee_port) - _radius(result.ports_m[0])) < 1e-6
    told = calibrate(sim.robot, sim.measurements, rig=replace(sim.rig_told, ports_m=guess[None]),
                     settings=PORT_SETTINGS)
    assert told.misfit is not None and told.misfit.misfit


def test_the_cli_finds_an_unknown_port_and_refuses_poses_on_a_plane(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`--port unknown --estimate-port` calibrates and says where the port came from (report
    and JSON); poses turning joint 1 alone (their points on one circle) cannot place a port:
    exit 2, one line; `--port unknown` without --estimate-port: exit 2, one line; a
    capture.toml's `port_mm = "unknown"` is the flag's."""
    sim = simulate(load_scenario(SCENARIO))
    data = tmp_path / "lengths.csv"
    write_measurements(data, sim.measurements, sim.robot)
    out = tmp_path / "result.json"
    assert main(["calibrate", str(data), "--port", "unknown", "--estimate-port",
                 "--json", str(out)]) == 0
    assert "nobody measured it: started from the lengths" in capsys.readouterr().out
    assert json.loads(out.read_text())["unknowns"]["rig"]["unknown_ports"] == ["port"]
    q = np.tile(sim.measurements.q_rad[:1], (60, 1))
    q[:, 0] = np.linspace(-2.0, 2.0, 60)
    lengths = np.linalg.norm(sim.robot.flange_positions(q) - sim.rig.ports_m[0], axis=1)
    circle = tmp_path / "circle.csv"
    write_measurements(circle, length_measurements(q, lengths), sim.robot)
    assert main(["calibrate", str(circle), "--port", "unknown", "--estimate-port"]) == 2
    err = capsys.readouterr().err.strip()
    assert "one plane" in err and "--port" in err and len(err.splitlines()) == 1, err
    assert main(["calibrate", str(data), "--port", "front=unknown"]) == 2
    err = capsys.readouterr().err.strip()
    assert "--estimate-port" in err and len(err.splitlines()) == 1, err
    capture = tmp_path / "capture.toml"
    robot = SCENARIO.parents[1] / "models" / "irb120.toml"
    capture.write_text(f'robot = "{robot}"\nport_mm = "unknown"\nmeasurements = "lengths.csv"\n')
    assert main(["calibrate", str(capture), "--estimate-port"]) == 0
    assert "nobody measured it: started from the lengths" in capsys.readouterr().out


@pytest.mark.parametrize("port", ["unknown", "front=unknown"])
def test_plan_needs_a_guess_of_the_port(tmp_path: Path, refusals: Refusals, port: str) -> None:
    """A plan chooses poses for where the cable runs: `--port unknown` is refused in one line
    saying a guess is needed (and that calibrate takes unknown), nothing written."""
    out = tmp_path / "plan.csv"
    refusals.cli(["plan", "--port", port, "--poses", "30", "--out", out], [],
                 f"--port: found --port {port}, expected the port's position X,Y,Z in mm")
    assert not out.exists()
