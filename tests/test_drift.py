"""Drift during a capture: the per-row columns (t_s, temperature_c, reference), the drift test
of the reference pose's readings against time, the twin's warm-up and the command line."""

from __future__ import annotations

import json
import math
import tomllib
from dataclasses import replace
from pathlib import Path

import matplotlib.image
import numpy as np
import pytest
from scipy import stats

from tests.conftest import Refusals
from twin.analysis.drift import ALPHA, reference_drift
from twin.analysis.misfit import repeat_sigma
from twin.cli import main
from twin.dataset import REFERENCE, TEMPERATURE, TIME, Measurements
from twin.errors import InputError
from twin.geometry.kinematics import point_position
from twin.io.measurements import load_measurements, write_measurements
from twin.kinds.length import length_measurements
from twin.scenario import load_scenario, parse_scenario
from twin.sim import simulate

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
THERMAL = SCENARIOS / "thermal_irb120.toml"


def _document(**thermal: object) -> dict:
    document = tomllib.loads(THERMAL.read_text(encoding="utf-8"))
    document["robot"] = str(SCENARIOS.parent / "models" / "irb120.toml")
    document["thermal"].update(thermal)
    return document


def _scenario(**thermal: object):
    return parse_scenario(_document(**thermal), THERMAL)


def test_row_columns_round_trip(tmp_path: Path) -> None:
    """t_s, temperature_c and reference are read beside a kind's readings and written back
    exactly."""
    rng = np.random.default_rng(0)
    q = rng.uniform(-1.0, 1.0, (5, 6))
    data = length_measurements(q, rng.uniform(0.5, 1.0, 5))
    data = replace(data, values={**data.values, TIME: np.arange(5) * 12.5,
                                 TEMPERATURE: 20.0 + rng.uniform(0, 3, 5),
                                 REFERENCE: np.array([1.0, 0, 0, 1, 0])})
    path = tmp_path / "m.csv"
    write_measurements(path, data)
    back = load_measurements(path)
    for name in (TIME, TEMPERATURE, REFERENCE):
        np.testing.assert_array_equal(back.value(name), data.value(name))
    assert "t_s,temperature_c,reference" in path.read_text().splitlines()[0]


@pytest.mark.parametrize(("column", "cell", "message"), [
    ("t_s", "-1", "line 2, column t_s: found -1, expected a time >= 0 s"),
    ("temperature_c", "293.15", "column temperature_c: found 293.15, expected a temperature in "
                                "°C within [-50, 150]"),
    ("reference", "2", "column reference: found 2, expected 1 on a reference pose"),
    ("reference", "yes", "column reference: found 'yes', expected a number"),
])
def test_bad_row_columns_are_refused(tmp_path: Path, refusals: Refusals, column: str,
                                     cell: str, message: str) -> None:
    """A bad time, temperature or flag: one line naming the file, line and column, exit 2."""
    path = tmp_path / "m.csv"
    path.write_text(f"q1,q2,q3,q4,q5,q6,length,{column}\n10,20,-30,40,-50,60,812.5,{cell}\n")
    error = refusals.cli(["calibrate", path, "--port", "600,-400,100"], [path], message)
    assert str(path) in error


def _series(slope_m_per_s: float, seed: int, sigma_m: float = 1e-5) -> Measurements:
    """Twelve readings of one pose at 300 s intervals among other poses, a line plus noise."""
    rng = np.random.default_rng(seed)
    m = 36
    q = rng.uniform(-1.0, 1.0, (m, 6))
    reference = np.zeros(m)
    reference[::3] = 1.0
    q[reference > 0] = q[0]
    t = np.arange(m) * 100.0
    length = 0.8 + slope_m_per_s * t + rng.normal(0.0, sigma_m, m)
    data = length_measurements(q, length)
    return replace(data, values={**data.values, TIME: t, REFERENCE: reference})


def test_the_slope_z_against_scipy() -> None:
    """The test's z is scipy's least-squares slope over its standard error for a known σ; its
    threshold is the two-sided normal quantile of level ALPHA."""
    data = _series(2e-8, seed=1)
    rows = np.flatnonzero(data.value(REFERENCE) > 0)
    drift = reference_drift(data, -data.value("length_m"), 1, 1e-5)
    assert drift is not None and len(drift.series) == 1
    t, y = data.value(TIME)[rows], data.value("length_m")[rows]
    fit = stats.linregress(t, y)
    sxx = float(np.sum((t - t.mean()) ** 2))
    noise = max(1e-5, math.sqrt(np.sum((y - fit.intercept - fit.slope * t) ** 2) / (t.size - 2)))
    assert drift.noise_m == pytest.approx(noise, rel=1e-9)
    assert drift.series[0].slope_m_per_s[0] == pytest.approx(fit.slope, rel=1e-9)
    assert drift.statistic == pytest.approx(abs(fit.slope) * math.sqrt(sxx) / noise, rel=1e-9)
    assert drift.threshold == pytest.approx(stats.norm.ppf(1 - ALPHA / 2), rel=1e-9)
    np.testing.assert_array_equal(drift.series[0].rows, rows)


def test_the_test_flags_a_drift_and_holds_its_level() -> None:
    """A drift of 0.1 mm over the hour is flagged on every seed; without drift the test fires
    at most about its level (none of 200 seeded captures at p 0.001)."""
    drifting = [reference_drift(d, -d.value("length_m"), 1, 1e-5)
                for d in (_series(1e-4 / 3600, seed) for seed in range(20))]
    assert all(d is not None and d.drift for d in drifting)
    quiet = [reference_drift(d, -d.value("length_m"), 1, 1e-5)
             for d in (_series(0.0, seed) for seed in range(200))]
    assert sum(d is not None and d.drift for d in quiet) <= 2


def test_revisits_of_a_reference_pose_are_not_repeat_readings() -> None:
    """A reference pose revisited over an hour of 0.1 mm drift is no measure of the noise: the
    misfit test keeps the stated σ (the revisits' spread, 3× it, would have passed a warm-up
    off as noise); the same rows unflagged are repeats again."""
    data = _series(1e-4 / 3600, seed=3)
    residuals = data.value("length_m") - 0.8
    assert repeat_sigma(data, residuals, 1) is None
    unflagged = replace(data, values={**data.values, REFERENCE: np.zeros(len(data))})
    spread = repeat_sigma(unflagged, residuals, 1)
    assert spread is not None and spread[0] > 3e-5 and spread[1] == 11


def test_no_reference_rows_no_test() -> None:
    """Without a reference column, or with too few readings, nothing is claimed."""
    data = _series(0.0, seed=0)
    bare = replace(data, values={"length_m": data.value("length_m")})
    assert reference_drift(bare, -bare.value("length_m"), 1, 1e-5) is None
    few = replace(data, values={**data.values,
                                REFERENCE: (np.arange(len(data)) < 4) * 1.0})
    drift = reference_drift(few, -few.value("length_m"), 1, 1e-5)
    assert drift is not None and not drift.series and not drift.drift


@pytest.mark.slow
def test_the_twin_grows_its_links_row_by_row() -> None:
    """Each row's cable length is the grown robot's: the true table plus the expansion times the
    temperature rise, at that row's actual joints (the core's kinematics, independent of the
    MuJoCo model the twin built for the row); the reference pose is revisited every 10 poses."""
    scenario = load_scenario(THERMAL)
    sim = simulate(scenario)
    thermal = scenario.thermal
    assert thermal is not None
    data = sim.measurements
    assert len(data) == len(thermal.visits(scenario.pose_count)) == 132
    reference = np.flatnonzero(data.value(REFERENCE) > 0)
    np.testing.assert_array_equal(reference, [*range(0, 132, 11), 131])
    temperature = data.value(TEMPERATURE)
    assert temperature[0] == pytest.approx(20.0) and temperature[-1] == pytest.approx(28.0)
    np.testing.assert_allclose(data.value(TIME), np.arange(132) * 30.0)
    port = sim.rig.ports_m[0]
    grown = np.stack([point_position(sim.true_robot.structure,
                                     sim.true_robot.dh + thermal.growth(temperature[k]),
                                     sim.q_actual_rad[k:k + 1])[0] for k in range(132)])
    np.testing.assert_allclose(np.linalg.norm(grown - port, axis=1), sim.true_length_m,
                               rtol=0, atol=1e-9)
    cold = np.linalg.norm(sim.true_robot.flange_positions(sim.q_actual_rad) - port, axis=1)
    moved = np.abs(sim.true_length_m - cold)[reference]
    assert moved[0] < 1e-9 and moved[-1] > 2e-5


def test_scenario_thermal_is_validated() -> None:
    """A [thermal] mistake names the key; touches cannot warm up."""
    with pytest.raises(InputError, match=r"ramp_k"):
        _scenario(ramp_k=500.0)
    with pytest.raises(InputError, match=r"seconds_per_pose"):
        _scenario(seconds_per_pose=0.0)
    with pytest.raises(InputError, match=r"a_um_per_k"):
        _scenario(a_um_per_k=[1.0, 2.0])
    with pytest.raises(InputError, match=r"reference_every"):
        _scenario(reference_every=-1)
    touches = tomllib.loads((SCENARIOS / "fixed_points_irb120.toml").read_text("utf-8"))
    touches["robot"] = str(SCENARIOS.parent / "models" / "irb120.toml")
    touches["thermal"] = {"ramp_k": 5.0}
    with pytest.raises(InputError, match=r"\[thermal\] with cable lengths"):
        simulate(parse_scenario(touches, SCENARIOS / "fixed_points_irb120.toml"))


@pytest.mark.slow
def test_calibrate_flags_a_warm_up_and_not_a_cold_capture(tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]
                                                          ) -> None:
    """simulate → calibrate: the warm capture's reference readings drift beyond the noise (the
    report and the result say so, the figure is written); the same capture at a constant
    temperature does not."""
    verdicts = {}
    for name, ramp in (("warm", 8.0), ("cold", 0.0)):
        scenario = tmp_path / f"{name}.toml"
        text = THERMAL.read_text(encoding="utf-8").replace(
            'robot = "../models/irb120.toml"',
            f'robot = "{(SCENARIOS.parent / "models" / "irb120.toml").as_posix()}"')
        scenario.write_text(text.replace("ramp_k = 8.0 ", f"ramp_k = {ramp} "), "utf-8")
        assert main(["simulate", str(scenario), "--out", str(tmp_path / name)]) == 0
        result, figure = tmp_path / f"{name}.json", tmp_path / f"{name}.png"
        capsys.readouterr()
        assert main(["calibrate", str(tmp_path / name / "capture.toml"), "--json", str(result),
                     "--drift-figure", str(figure)]) == 0
        report = capsys.readouterr().out
        drift = json.loads(result.read_text())["drift"]
        assert drift["reference_rows"] == 13 and drift["tests"] == 1
        assert len(drift["series"][0]["readings"]) == 13
        assert ("DRIFT beyond the noise" in report) == drift["drift"]
        assert matplotlib.image.imread(figure).shape[2] in (3, 4)
        verdicts[name] = (drift["drift"], drift["z"], drift["threshold"])
    assert verdicts["warm"][0] and verdicts["warm"][1] > 2 * verdicts["warm"][2]
    assert not verdicts["cold"][0]
    # A rigid fit of the warm capture misses the growth: the misfit says so and names it.
    assert main(["calibrate", str(tmp_path / "warm" / "capture.toml"), "--errors", "dh"]) == 0
    report = capsys.readouterr().out
    assert "MISFIT" in report and "growth with temperature (--errors dh,thermal)" in report


def test_drift_figure_needs_reference_rows(tmp_path: Path, refusals: Refusals) -> None:
    """--drift-figure on data without a reference pose is refused in one line, nothing
    written."""
    path = Path(__file__).resolve().parents[1] / "examples" / "irb120_lm" / "measurements.csv"
    refusals.cli(["calibrate", path, "--port", "600,-400,100", "--drift-figure",
                  tmp_path / "d.png"], [path], "--drift-figure: " + str(path)
                 + ": found 0 row(s) flagged reference")
    assert not (tmp_path / "d.png").exists()
