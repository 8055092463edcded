"""Scenario files: every shipped scenario loads and simulates; mistakes are named clearly."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from twin.errors import InputError
from twin.scenario import load_scenario, parse_scenario
from twin.sim import simulate

SCENARIOS = sorted((Path(__file__).parents[1] / "scenarios").glob("*.toml"))
PAPER = Path(__file__).parents[1] / "scenarios" / "paper_irb120.toml"


def test_the_shipped_scenarios_are_there() -> None:
    """The issue's two scenarios are shipped."""
    names = {path.stem for path in SCENARIOS}
    assert {"geometric_irb120", "paper_irb120"} <= names


@pytest.mark.slow
@pytest.mark.parametrize("path", SCENARIOS, ids=lambda p: p.stem)
def test_every_scenario_loads_and_simulates(path: Path) -> None:
    """Each file in scenarios/ validates and gives a capture of the poses it asks for, with a
    finite reading of its kind on every row."""
    scenario = load_scenario(path)
    sim = simulate(scenario)
    expected = scenario.pose_count or len(sim.measurements)
    if scenario.thermal is not None:  # the first pose revisited
        expected = len(scenario.thermal.visits(expected))
    assert len(sim.measurements) == expected
    data = sim.measurements
    assert data.values or data.labels
    for column in data.values.values():
        assert np.all(np.isfinite(column))


def _document(**changes: object) -> dict:
    document = tomllib.loads(PAPER.read_text())
    for dotted, value in changes.items():
        table, _, key = dotted.rpartition("__")
        target = document.setdefault(table, {}) if table else document
        if value is None:
            target.pop(key, None)
        else:
            target[key] = value
    return document


@pytest.mark.parametrize(
    ("changes", "where", "found"),
    [
        ({"colour": "red"}, "scenario.toml", "unknown key 'colour'"),
        ({"seed": None}, "seed", "nothing"),
        ({"seed": 1.5}, "seed", "1.5"),
        ({"port__position_mm": [1.0, 2.0]}, "[port] position_mm", "[1.0, 2.0]"),
        ({"port__told_mm": [1.0, 2.0, 3.0], "port__told_error_mm": 0.1}, "[port] told_mm",
         "both"),
        ({"perturbation__distribution": "cauchy"}, "[perturbation] distribution", "'cauchy'"),
        ({"perturbation__a_mm": -1.0}, "[perturbation] a_mm", "-1.0"),
        ({"poses__count": 0}, "[poses] count", "0"),
        ({"encoder__sigma_mm": "small"}, "[encoder] sigma_mm", "'small'"),
        ({"encoder__range_mm": [900.0, 100.0]}, "[encoder] range_mm", "[900.0, 100.0]"),
        ({"encoder__outlier_rate": 0.05}, "[encoder] outlier_mm", "0 with outlier_rate"),
        ({"joints__transmission_harmonic": 1.5}, "[joints] transmission_harmonic", "1.5"),
        ({"joints__backlash_arcsec": [1.0, 2.0]}, "[joints] backlash_arcsec", "[1.0, 2.0]"),
        ({"physics__stiffness_nm_per_rad": None}, "[physics] stiffness_nm_per_rad", "nothing"),
        ({"physics__compliance": False}, "[physics] stiffness_nm_per_rad", "compliance = false"),
        ({"calibration__train_fraction": 1.5}, "[calibration] train_fraction", "1.5"),
        ({"calibration__errors": ["dh", "gears"]}, "[calibration] errors", "'gears'"),
        ({"calibration__errors": []}, "[calibration] errors", "[]"),
        ({"physics__mass_error": 1.5}, "[physics] mass_error", "1.5"),
        ({"physics__compliance": False, "physics__stiffness_nm_per_rad": None,
          "physics__gravity": None, "physics__tension_n": None, "physics__mass_error": 0.2},
         "[physics] mass_error", "compliance = false"),
        ({"measurement__kind": "position", "port": None, "encoder__scale_ppm": 50.0},
         "[encoder] scale_ppm", "scale_ppm with tracker positions"),
        ({"measurement__kind": "position", "port": None, "encoder__offset_mm": 0.5},
         "[encoder] offset_mm", "offset_mm with tracker positions"),
        ({"study": 3}, "[study]", "3"),
        ({"expect": ["lm"]}, "[expect]", "['lm']"),
    ],
)
def test_mistakes_name_file_key_and_expectation(changes: dict, where: str, found: str) -> None:
    """Each mistake is one InputError naming the file, the key and what was found."""
    source = Path("scenarios/scenario.toml")
    with pytest.raises(InputError) as caught:
        parse_scenario(_document(**changes), source)
    message = str(caught.value)
    assert str(source) in message and where in message and found in message
    assert "expected" in message


def test_study_and_expect_tables_are_passed_through_unread() -> None:
    """[study] and [expect] tables with any content are kept as written for twin.study."""
    study = {"trials": 50, "methods": ["lm", "m9"], "sweep": {"encoder.sigma_mm": [0.001, 0.01]}}
    expect = {"lm": ["flange_error_mm p95 <= 0.03"], "*": ["anything, read by twin check"]}
    scenario = parse_scenario(_document(study=study, expect=expect), PAPER)
    assert scenario.study == study and scenario.expect == expect


def test_missing_file_and_bad_toml_are_input_errors(tmp_path: Path) -> None:
    """A missing file or broken TOML is reported as an InputError naming the file."""
    with pytest.raises(InputError, match="no such file"):
        load_scenario(tmp_path / "nope.toml")
    broken = tmp_path / "broken.toml"
    broken.write_text("name = \n")
    with pytest.raises(InputError, match=r"broken\.toml: found invalid TOML"):
        load_scenario(broken)


def test_units_are_converted_once() -> None:
    """mm, degrees and arc-seconds in the file become m and rad in the scenario."""
    scenario = load_scenario(PAPER)
    assert np.allclose(scenario.port_m, [0.6, -0.4, 0.1])
    assert scenario.noise.resolution_m == pytest.approx(4e-6)
    assert scenario.noise.repeatability_m == pytest.approx(1e-5)
    assert scenario.perturbation.scale[2, 0] == pytest.approx(np.deg2rad(0.2))
    assert scenario.joint_errors is not None
    assert scenario.joint_errors.transmission_rad[0] == pytest.approx(np.deg2rad(240 / 3600))
    assert scenario.joint_errors.harmonic.tolist() == [1, 1, 1, 2, 2, 2]
    assert scenario.physics.stiffness_nm_per_rad is not None
    assert scenario.calibration.train_fraction == 0.8


def test_perturbation_draws_each_slot_in_its_unit() -> None:
    """On a robot with Hayati joints (the UR5e from its URDF: joints 2 and 3) the second slot
    is β there, an angle: it draws from beta_deg (by default alpha_deg), never from d_mm, and is
    clipped to ±8°, the lengths to ±5 mm."""
    path = Path(__file__).parents[1] / "scenarios" / "geometric_ur5e.toml"
    document = tomllib.loads(path.read_text())
    scenario = parse_scenario(document, path)
    hayati = ~scenario.robot.is_length[1]
    assert list(np.flatnonzero(hayati)) == [1, 2]
    scale = scenario.perturbation.scale
    np.testing.assert_allclose(scale[1, hayati], np.deg2rad(0.2))  # alpha_deg's
    np.testing.assert_allclose(scale[1, ~hayati], 1.5e-3)
    document["perturbation"].update(beta_deg=20.0, d_mm=20.0)
    wide = parse_scenario(document, path)
    np.testing.assert_allclose(wide.perturbation.scale[1, hayati], np.deg2rad(20.0))
    delta = wide.perturbation.draw(np.random.default_rng(0))
    assert np.all(np.abs(delta[1, ~hayati]) <= 5e-3 + 1e-15)
    assert np.all(np.abs(delta[1, hayati]) <= np.deg2rad(8.0) + 1e-15)
    assert np.any(np.abs(delta[1, hayati]) > 5e-3)  # an angle, not clipped as a length
