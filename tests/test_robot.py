"""Robot model files: the shipped IRB 120, round trips and clear errors."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from twin.errors import InputError
from twin.robot import RobotModel, load_robot, parse_robot, robot_to_toml

ROOT = Path(__file__).resolve().parents[1]


def test_shipped_model_equals_models_file() -> None:
    """The packaged default is the content of models/irb120.toml."""
    from twin.robot import default_robot

    from_file = load_robot(ROOT / "models" / "irb120.toml")
    packaged = default_robot()
    np.testing.assert_array_equal(from_file.dh, packaged.dh)
    assert from_file.name == "ABB IRB 120"
    np.testing.assert_allclose(np.rad2deg(from_file.upper_rad), [165, 110, 70, 160, 120, 400])


def test_toml_round_trip(irb120: RobotModel, tmp_path: Path) -> None:
    """robot_to_toml rounds lengths to 1 µm and angles to 1e-6 degree; load_robot reads back
    exactly the numbers written, so writing the robot read back gives the same bytes."""
    robot = irb120.perturbed(np.full(24, 1e-4) + np.random.default_rng(3).normal(0, 1e-5, 24))
    text = robot_to_toml(robot)
    path = tmp_path / "robot.toml"
    path.write_text(text)
    back = load_robot(path)
    assert robot_to_toml(back) == text
    lengths, angles = back.dh[:2] - robot.dh[:2], np.rad2deg(back.dh[2:] - robot.dh[2:])
    assert np.max(np.abs(lengths)) <= 0.5e-6 + 1e-15 and np.max(np.abs(lengths)) > 0
    assert np.max(np.abs(angles)) <= 0.5e-6 + 1e-12
    for line in text.splitlines()[5:-1]:  # no float noise: at most 6 decimals per number
        for value in re.findall(r"-?\d+\.\d+", line):
            assert len(value.split(".")[1]) <= 6, line
    assert back.mass_kg is not None and back.radius_m is not None
    assert back.com_m is not None and robot.com_m is not None
    assert np.max(np.abs(back.com_m - robot.com_m)) <= 0.5e-6 + 1e-15


def test_metres_and_radians_are_accepted() -> None:
    """length_unit = "m" and angle_unit = "rad" are converted, not misread."""
    joint = {"a": 0.1, "d": 0.2, "alpha": 0.5, "theta": 0.0, "lower": -1.0, "upper": 1.0}
    robot = parse_robot({"name": "x", "convention": "dh", "length_unit": "m",
                         "angle_unit": "rad", "joints": [joint] * 6}, "x.toml")
    assert robot.dh[0, 0] == 0.1 and robot.dh[2, 0] == 0.5


BASE = 'name = "x"\nconvention = "dh"\nlength_unit = "mm"\nangle_unit = "deg"\n'
JOINT = "{ a = 0.0, d = 290.0, alpha = -90.0, theta = 0.0, lower = -165.0, upper = 165.0 }"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (BASE.replace('"mm"', '"inch"') + f"joints = [{', '.join([JOINT] * 6)}]", "length_unit"),
        (BASE.replace('length_unit = "mm"\n', "") + f"joints = [{', '.join([JOINT] * 6)}]",
         "no 'length_unit'"),
        (BASE + f"joints = [{', '.join([JOINT] * 5)}]", "5 joints"),
        (BASE + f"joints = [{', '.join([JOINT.replace('290.0', 'nan')] + [JOINT] * 5)}]",
         "joint 1: found d = nan"),
        (BASE + f"joints = [{', '.join([JOINT.replace('a = 0.0', 'b = 0.0')] + [JOINT] * 5)}]",
         "unknown key 'b'"),
        (BASE + "colour = 1\n" + f"joints = [{', '.join([JOINT] * 6)}]", "unknown key 'colour'"),
        (BASE + f"joints = [{', '.join([JOINT.replace('-165.0', '170.0')] + [JOINT] * 5)}]",
         "lower < upper"),
        (BASE.replace('"dh"', '"mdh"') + f"joints = [{', '.join([JOINT] * 6)}]", "convention"),
        ("joints = [", "invalid TOML"),
    ],
)
def test_bad_model_files(tmp_path: Path, text: str, message: str) -> None:
    """Each mistake is one InputError naming the file and what was wrong."""
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(InputError) as info:
        load_robot(path)
    assert str(path) in str(info.value) and message in str(info.value)


def test_missing_model_file(tmp_path: Path) -> None:
    """A missing file is named."""
    with pytest.raises(InputError, match="no such file"):
        load_robot(tmp_path / "nope.toml")
