"""Capture sessions on the twin (seeded): a ``session`` column gives each session its own
encoder zero, recovered against the truth and scipy's least_squares; without the column the
step diagnosis names the row where the readings jump, and a capture without a step names
none. The false-alarm level of that last check is the detector's ALPHA = 1e-3 for the one
step-free capture (Bonferroni over its 119 places; the seed is fixed)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import least_squares

from twin.calibration.pipeline import calibrate
from twin.cli import main
from twin.dataset import Labels, Measurements
from twin.io.measurements import load_measurements, write_measurements
from twin.kinds.length import LENGTH
from twin.scenario import load_scenario
from twin.sim import Simulation, simulate
from twin.study.trial import noise_sigma_m, true_unknowns

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "geometric_irb120.toml"
STEP_M = 3e-3
"""The cable re-hooked between the sessions: every later reading 3 mm longer."""


def _stepped(sim: Simulation, sessions: bool) -> tuple[Measurements, int]:
    """The twin's capture with the readings from the middle row on 3 mm longer, labelled by
    session or not; and that row."""
    data = sim.measurements
    row = len(data) // 2
    after = np.arange(len(data)) >= row
    labels = {**data.labels}
    if sessions:
        labels["session"] = Labels(("morning", "afternoon"), after.astype(np.intp))
    return Measurements(data.q_rad, data.kind, {LENGTH: data.value(LENGTH) + STEP_M * after},
                        labels, data.approach), row


@pytest.mark.slow
def test_each_session_gets_its_own_zero() -> None:
    """Two sessions 3 mm apart: the zeros come back within 2× their Cramér–Rao σ of the truth
    (0 and +3 mm: the model adds the offset to the modelled length), scipy from the same start
    agrees to 0.2σ, the fit is no misfit and no step is left."""
    sim = simulate(load_scenario(SCENARIO))
    data, _ = _stepped(sim, sessions=True)
    result = calibrate(sim.robot, data, rig=sim.rig_told)
    model = result.model
    assert model.rig.sessions == ("morning", "afternoon")
    train = model.kind.prepare(sim.robot, model.rig, data, result.settings.noise)[1] \
        .subset(result.train_rows)
    x_true = true_unknowns(sim, model)
    x_true[model.slice("offset")] = [0.0, STEP_M]
    jacobian = model.jacobian(x_true, train)[1]
    covariance = np.linalg.pinv(jacobian.T @ jacobian) * noise_sigma_m(sim, jacobian) ** 2
    sigma = np.sqrt(np.diag(covariance)[model.slice("offset")])
    assert np.all(np.abs(result.offsets_m - [0.0, STEP_M]) < 2 * sigma), \
        (result.offsets_m, sigma)
    lower, upper = model.bounds()
    referee = least_squares(lambda x: model.residuals(x, train), np.zeros(model.n_params),
                            bounds=(lower, upper), x_scale="jac", xtol=1e-12, ftol=1e-12,
                            gtol=1e-12).x
    assert np.all(np.abs(model.block(referee, "offset") - result.offsets_m) < 0.2 * sigma)
    assert result.misfit is not None and not result.misfit.misfit
    assert result.steps == ()


def test_a_step_is_named_at_its_row_and_a_capture_without_one_names_none() -> None:
    """Without the session column the fit is a misfit whose residuals step at the middle row
    by the readings' +3 mm (to 0.05 mm); the twin's own capture reports no step."""
    sim = simulate(load_scenario(SCENARIO))
    data, row = _stepped(sim, sessions=False)
    result = calibrate(sim.robot, data, rig=sim.rig_told)
    assert result.misfit is not None and result.misfit.misfit
    (step,) = result.steps
    assert step.row == row and -step.size_m == pytest.approx(STEP_M, abs=5e-5)
    assert calibrate(sim.robot, sim.measurements, rig=sim.rig_told).steps == ()


@pytest.mark.slow
def test_the_session_column_through_the_cli(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    """A CSV with a session column round-trips; `twin calibrate` prints each session's zero
    and writes them to the JSON; without the column it names the step in the report (the
    misfit line too) and the JSON; an empty session cell is refused in one line."""
    sim = simulate(load_scenario(SCENARIO))
    data, row = _stepped(sim, sessions=True)
    path = tmp_path / "sessions.csv"
    write_measurements(path, data, sim.robot)
    read = load_measurements(path, sim.robot)
    assert read.names("session") == ("morning", "afternoon")
    port = ",".join(f"{v:.6f}" for v in sim.rig_told.ports_m[0] * 1e3)
    out = tmp_path / "r.json"
    assert main(["calibrate", str(path), "--port", port, "--json", str(out)]) == 0
    assert "identified length offset, session afternoon: 2.99" in capsys.readouterr().out
    assert json.loads(out.read_text())["offsets"]["afternoon"] == pytest.approx(3.0, abs=0.01)
    plain = tmp_path / "plain.csv"
    write_measurements(plain, _stepped(sim, sessions=False)[0], sim.robot)
    assert main(["calibrate", str(plain), "--port", port, "--json", str(out)]) == 0
    printed = capsys.readouterr().out
    assert f"the residuals step at data row(s) {row}" in printed
    assert "STEPS: the readings jump against the model at 1 place(s)" in printed
    (found,) = json.loads(out.read_text())["steps"]["found"]
    assert found["row"] == row and found["reading_jump"] == pytest.approx(3.0, abs=0.05)
    lines = path.read_text().splitlines()
    column = lines[0].split(",").index("session")
    cells = lines[3].split(",")
    lines[3] = ",".join([*cells[:column], " ", *cells[column + 1:]])
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(lines) + "\n")
    assert main(["calibrate", str(bad), "--port", port]) == 2
    err = capsys.readouterr().err.strip()
    assert "line 4, column session" in err and len(err.splitlines()) == 1, err
