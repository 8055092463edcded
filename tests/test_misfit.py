"""The misfit test: chi-square of the training residuals against the noise the data imply."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import chi2

from twin.analysis.misfit import ALPHA, FAR, chi2_quantile, misfit_test, reading_sigma, repeat_sigma
from twin.calibration.pipeline import calibrate
from twin.calibration.settings import CalibrationSettings
from twin.kinds.length import length_measurements
from twin.robot import RobotModel, random_poses
from twin.scenario import Scenario, load_scenario
from twin.sim import simulate
from twin.synthetic import synthesize


@pytest.mark.parametrize("dof", [1, 7, 73, 1000])
def test_the_quantile_is_scipys(dof: int) -> None:
    """The χ² quantile equals scipy.stats.chi2.ppf."""
    assert chi2_quantile(1 - ALPHA, dof) == pytest.approx(chi2.ppf(1 - ALPHA, dof), rel=1e-10)


def test_the_p_value_is_scipys_and_decides_as_the_threshold() -> None:
    """A misfit's p-value is scipy.stats.chi2.sf of its statistic, and p < ALPHA exactly where
    the statistic is above the quantile, on residuals from the noise to ten times it."""
    rng = np.random.default_rng(4)
    sigma = 1e-5
    for factor in (0.8, 1.0, 1.05, 1.1, 1.3, 3.0, 10.0):
        found = misfit_test(rng.normal(0, factor * sigma, 400), 24, sigma)
        reference = chi2.sf(found.statistic, found.dof)
        assert found.p_value == pytest.approx(reference, rel=1e-9, abs=1e-300)
        assert (found.p_value < ALPHA) == found.misfit


def test_noise_passes_and_a_model_error_does_not() -> None:
    """Residuals of the stated noise pass; three times the noise fails; a noise 20 % above the
    stated one on many rows rejects χ² and is a misfit too — the test decides on χ² alone, and
    says both readings, the second with the σ the residuals imply."""
    rng = np.random.default_rng(0)
    sigma = 1e-5
    assert not misfit_test(rng.normal(0, sigma, 100), 20, sigma).misfit
    bad = misfit_test(rng.normal(0, 3 * sigma, 100), 20, sigma)
    assert bad.misfit and bad.statistic > bad.threshold and bad.ratio > FAR
    mild = misfit_test(rng.normal(0, 1.2 * sigma, 5000), 20, sigma)
    assert mild.statistic > mild.threshold and mild.misfit and mild.ratio < FAR
    assert mild.implied_sigma_m == pytest.approx(1.2 * sigma, rel=0.05)
    assert "model misses something" in mild.readings() and "1.2" in mild.readings()


def test_repeat_readings_measure_the_noise(irb120: RobotModel, true_robot: RobotModel,
                                           port_m: np.ndarray) -> None:
    """Each of 40 poses read three times with σ = 0.05 mm: the pooled spread measures 0.05 mm,
    and a calibration told σ = 0.01 mm tests against the measured noise — no misfit."""
    rng = np.random.default_rng(1)
    q = np.repeat(random_poses(irb120, 40, rng), 3, axis=0)
    data = synthesize(true_robot, q, port_m, 5e-5, rng)
    measured = repeat_sigma(data, data.value("length_m") - np.repeat(
        synthesize(true_robot, q[::3], port_m, 0.0, rng).value("length_m"), 3), 1)
    assert measured is not None and measured[1] == 80
    assert measured[0] == pytest.approx(5e-5, rel=0.2)
    result = calibrate(irb120, length_measurements(q, data.value("length_m")), port_m,
                       settings=CalibrationSettings(sigma_m=1e-5))
    assert result.misfit is not None and not result.misfit.misfit
    assert result.misfit.noise_source.startswith("repeat readings")
    assert result.misfit.noise_m == pytest.approx(5e-5, rel=0.3)


@pytest.mark.slow
def test_the_robots_repeatability_is_noise() -> None:
    """The twin's joint jitter (0.01 mm RMS at the flange) on a 0.002 mm encoder: a D-H fit
    leaves about the r/√3 the stated noise of a reading adds (the twin's MuJoCo jitter is the
    referee of that model), so told the repeatability it is no misfit, and told the encoder's
    noise alone it is one."""
    from twin.scenario import parse_scenario
    from twin.sim import simulate

    document = {"name": "jitter", "seed": 4, "port": {"position_mm": [600.0, -400.0, 100.0]},
                "perturbation": {"a_mm": 1.0, "d_mm": 1.0, "alpha_deg": 0.1, "theta_deg": 0.1},
                "poses": {"count": 400}, "encoder": {"sigma_mm": 0.002, "resolution_mm": 0.0},
                "joints": {"repeatability_mm": 0.01}}
    sim = simulate(parse_scenario(document, Path("jitter.toml")))
    encoder_m, repeatability_m = 2e-6, 1e-5
    told = reading_sigma(encoder_m, repeatability_m)
    assert told == pytest.approx(np.hypot(2e-6, 1e-5 / np.sqrt(3)))
    result = calibrate(sim.robot, sim.measurements, sim.port_nominal_m,
                       settings=CalibrationSettings(sigma_m=told))
    assert result.misfit is not None and not result.misfit.misfit, result.misfit
    assert 0.8 * told < result.metrics["validation"].rmse < 1.25 * told
    alone = calibrate(sim.robot, sim.measurements, sim.port_nominal_m,
                      settings=CalibrationSettings(sigma_m=encoder_m))
    assert alone.misfit is not None and alone.misfit.misfit, alone.misfit


def _geometric(tmp_path: Path, extra: str = "") -> Scenario:
    """The twin's geometric IRB 120 scenario, with ``extra`` TOML appended."""
    scenarios = Path(__file__).resolve().parents[1] / "scenarios"
    text = (scenarios / "geometric_irb120.toml").read_text().replace(
        'robot = "../models/irb120.toml"', f'robot = "{scenarios.parent}/models/irb120.toml"')
    path = tmp_path / f"s{len(list(tmp_path.iterdir()))}.toml"
    path.write_text(text + extra)
    return load_scenario(path)


def _flags(scenario: Scenario, seeds: range, scale: float = 0.0) -> int:
    """How many seeds' D-H calibrations the misfit test flags (lengths read × (1 + scale))."""
    flagged = 0
    for seed in seeds:
        sim = simulate(scenario, seed)
        data = replace(sim.measurements, values={
            "length_m": sim.measurements.value("length_m") * (1.0 + scale)})
        result = calibrate(sim.robot, data, rig=sim.rig_told_pulled,
                           settings=scenario.calibration, seed=seed)
        assert result.misfit is not None
        flagged += result.misfit.misfit
    return flagged


@pytest.mark.slow
def test_the_test_flags_what_a_dh_model_misses_and_is_quiet_on_clean_data(
        tmp_path: Path) -> None:
    """On the twin: clean data (the model explains them) are flagged in at most 1 of 10 seeds
    (the level is 1 in 1000); a missed 60″ third-harmonic transmission error, and an encoder
    scale error of 100 ppm, each in at least 4 of 5."""
    clean = _geometric(tmp_path)
    assert _flags(clean, range(10)) <= 1
    harmonic = _geometric(tmp_path, "\n[joints]\ntransmission_arcsec = 60.0\n"
                          "transmission_harmonic = 3\n")
    assert _flags(harmonic, range(5)) >= 4
    assert _flags(clean, range(5), scale=1e-4) >= 4
