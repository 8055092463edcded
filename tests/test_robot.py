"""Robot model files: the shipped IRB 120, round trips and clear errors."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from twin.errors import InputError
from twin.io.robot_file import load_robot, parse_robot, robot_files, robot_to_toml
from twin.robot import RobotModel

ROOT = Path(__file__).resolve().parents[1]


def test_shipped_model_equals_models_file() -> None:
    """The packaged default is the content of models/irb120.toml."""
    from twin.io.robot_file import default_robot

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
HELICAL = JOINT.replace("{ ", '{ type = "helical", ')
SLIDE = JOINT.replace("{ ", '{ type = "prismatic", ')


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (BASE.replace('"mm"', '"inch"') + f"joints = [{', '.join([JOINT] * 6)}]", "length_unit"),
        (BASE.replace('length_unit = "mm"\n', "") + f"joints = [{', '.join([JOINT] * 6)}]",
         "length_unit: found nothing, expected one of mm, m"),
        (BASE + f"joints = [{', '.join([JOINT] * 3)}]", "3 joints"),
        (BASE + f"joints = [{', '.join([JOINT] * 10)}]", "10 joints"),
        (BASE + f"joints = [{', '.join([JOINT.replace('290.0', 'nan')] + [JOINT] * 5)}]",
         "joint 1 d: found nan, expected a number within ±100000 mm"),
        (BASE + f"joints = [{', '.join([JOINT.replace('a = 0.0', 'b = 0.0')] + [JOINT] * 5)}]",
         "unknown key 'b'"),
        (BASE + "colour = 1\n" + f"joints = [{', '.join([JOINT] * 6)}]", "unknown key 'colour'"),
        (BASE + f"joints = [{', '.join([JOINT.replace('-165.0', '170.0')] + [JOINT] * 5)}]",
         "lower < upper"),
        (BASE.replace('"dh"', '"mdh"') + f"joints = [{', '.join([JOINT] * 6)}]", "convention"),
        (BASE.replace('convention = "dh"', 'parametrisation = ["mdh", "dh", "dh", "dh", "dh", '
                      '"dh"]') + f"joints = [{', '.join([JOINT] * 6)}]", "whole chain"),
        (BASE.replace('convention = "dh"', 'parametrisation = "craig"')
         + f"joints = [{', '.join([JOINT] * 6)}]", "parametrisation = 'craig'"),
        (BASE.replace('convention = "dh"', 'parametrisation = ["hayati", "dh", "dh", "dh", '
                      '"dh", "dh"]') + f"joints = [{', '.join([JOINT] * 6)}]",
         "joint 1: found unknown key 'd', expected only type, a, beta"),
        (BASE + f"joints = [{', '.join([HELICAL] + [JOINT] * 5)}]",
         "joint 1 type: found 'helical', expected one of revolute, prismatic"),
        (BASE + f"joints = [{', '.join([SLIDE.replace('165.0 }', '2e6 }')] + [JOINT] * 5)}]",
         "joint 1 upper: found 2000000.0, expected a number within ±100000 mm"),
        (BASE + f"joints = [{', '.join([SLIDE.replace(' }', ', effort = -1.0 }')] + [JOINT] * 5)}]",
         "joint 1 effort: found -1.0, expected a number from 0 to 1e+06 N"),
        (BASE + f"joints = [{', '.join([JOINT] * 6)}]\nbase = {{ xyz = [1.0, 2.0] }}",
         "[base] xyz: found [1.0, 2.0], expected [x, y, z]"),
        (BASE + f"joints = [{', '.join([JOINT.replace(' }', ', velocity = -1.0 }')] * 6)}]",
         "joint 1 velocity: found -1.0, expected a number from 0 to 5729.58 deg/s"),
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


SIX = "\n".join([
    "  { a = 0.0, d = 290.0, alpha = -90.0, theta = 0.0, lower = -165.0, upper = 165.0 },",
    "  { a = 270.0, d = 0.0, alpha = 0.0, theta = -90.0, lower = -110.0, upper = 110.0 },",
    "  { a = 70.0, d = 0.0, alpha = -90.0, theta = 0.0, lower = -110.0, upper = 70.0 },",
    "  { a = 0.0, d = 302.0, alpha = 90.0, theta = 0.0, lower = -160.0, upper = 160.0 },",
    "  { a = 0.0, d = 0.0, alpha = -90.0, theta = 0.0, lower = -120.0, upper = 120.0 },",
    "  { a = 0.0, d = 72.0, alpha = 0.0, theta = 0.0, lower = -400.0, upper = 400.0 },",
])


def _model(tmp_path: Path, header: str, rows: str = SIX, tail: str = "") -> RobotModel:
    path = tmp_path / "robot.toml"
    path.write_text('name = "x"\nlength_unit = "mm"\nangle_unit = "deg"\n' + header
                    + f"\njoints = [\n{rows}\n]\n" + tail)
    return load_robot(path)


def test_auto_makes_parallel_axes_hayati_with_the_same_flange(tmp_path: Path) -> None:
    """parametrisation = "auto" reads standard D-H rows and turns joint 2 of the IRB 120 (axes
    2 and 3 parallel) into a Hayati joint; the flange stays where the D-H rows put it."""
    dh = _model(tmp_path, 'parametrisation = "dh"')
    auto = _model(tmp_path, 'parametrisation = "auto"')
    assert dh.structure.parametrisation == ("dh",) * 6
    assert auto.structure.parametrisation == ("dh", "hayati", "dh", "dh", "dh", "dh")
    assert not auto.is_length[1, 1] and auto.structure.parameter_names[7] == "beta2"
    q = np.random.default_rng(0).uniform(dh.lower_rad, dh.upper_rad, (200, 6))
    np.testing.assert_allclose(auto.flange_transforms(q), dh.flange_transforms(q), atol=1e-12)


def test_rows_in_their_own_parametrisation_with_ends_round_trip(tmp_path: Path) -> None:
    """A list of parametrisations takes each row in its own slots (a Hayati row's beta is an
    angle); base and tool are xyz (mm) and rpy (deg) transforms; velocity and effort are read.
    robot_to_toml writes it all back and reads back to the same bytes."""
    lines = SIX.replace("{ a = 270.0, d = 0.0,", "{ a = 270.0, beta = 0.5,").splitlines()
    limits = [", velocity = 250.0, effort = 40.0 },"] * 5 + [", velocity = 420.0, effort = 2.5 },"]
    rows = "\n".join(line[:-3] + extra for line, extra in zip(lines, limits, strict=True))
    robot = _model(tmp_path, 'parametrisation = ["dh", "hayati", "dh", "dh", "dh", "dh"]', rows,
                   "base = { xyz = [10.0, 0.0, 5.0], rpy = [0.0, 0.0, 90.0] }\n"
                   "tool = { xyz = [0.0, 0.0, 25.0], rpy = [180.0, 0.0, 0.0] }\n")
    assert robot.dh[1, 1] == pytest.approx(np.deg2rad(0.5), abs=1e-15)
    np.testing.assert_allclose(robot.structure.base[:3, 3], [0.01, 0.0, 0.005])
    np.testing.assert_allclose(robot.structure.tool[:3, :3], np.diag([1.0, -1.0, -1.0]),
                               atol=1e-15)
    assert robot.velocity_rad_s is not None and robot.effort_nm is not None
    np.testing.assert_allclose(robot.effort_nm, [40.0] * 5 + [2.5])
    text = robot_to_toml(robot)
    path = tmp_path / "again.toml"
    path.write_text(text)
    back = load_robot(path)
    assert robot_to_toml(back) == text
    q = np.random.default_rng(1).uniform(-1.0, 1.0, (50, 6))
    np.testing.assert_allclose(back.flange_transforms(q), robot.flange_transforms(q), atol=1e-9)


@pytest.mark.parametrize("n", [4, 7, 9])
def test_four_to_nine_joints(tmp_path: Path, n: int) -> None:
    """Chains of 4, 7 and 9 joints are robots like any other."""
    lines = SIX.splitlines()
    rows = "\n".join(lines[:n] if n <= 6 else lines + lines[-1:] * (n - 6))
    robot = _model(tmp_path, 'parametrisation = "mdh"', rows)
    assert robot.n_joints == n and robot.structure.parametrisation == ("mdh",) * n
    assert robot.joint_names == tuple(f"joint_{i}" for i in range(1, n + 1))


def test_a_model_file_may_name_a_urdf(tmp_path: Path) -> None:
    """urdf = "…" reads the URDF (relative to the file) with the links and parametrisation
    given; robot_files writes such a robot as the URDF and a file naming it, which reads back to
    the same robot."""
    source = ROOT / "models" / "ur5e" / "ur5e.urdf"
    (tmp_path / "arm.urdf").write_text(source.read_text())
    (tmp_path / "arm.toml").write_text('urdf = "arm.urdf"\nname = "my UR5e"\n'
                                       'tip_link = "flange"\nparametrisation = "dh"\n')
    robot = load_robot(tmp_path / "arm.toml")
    assert robot.name == "my UR5e" and robot.urdf is not None
    assert robot.urdf.tip_link == "flange" and robot.structure.parametrisation == ("dh",) * 6
    files = robot_files(robot, "copy")
    assert set(files) == {"copy.toml", "copy.urdf"}
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    back = load_robot(tmp_path / "copy.toml")
    np.testing.assert_array_equal(back.dh, robot.dh)
    assert back.name == robot.name and back.urdf is not None
    assert (back.urdf.text, back.urdf.tip_link, back.urdf.joint_names) == (
        robot.urdf.text, robot.urdf.tip_link, robot.urdf.joint_names)
    with pytest.raises(ValueError, match="reference"):
        robot_to_toml(robot)


def test_prismatic_joints_in_a_model_file(tmp_path: Path) -> None:
    """``type = "prismatic"`` makes a sliding joint: its limits and speed in the length unit,
    its effort in N; auto converts the chain keeping the types; the file written back says the
    type, in mm, and reads back to the same robot (same FK, q of the slide in m)."""
    lines = [line.replace(" },", ", velocity = 90.0, effort = 50.0 },")
             for line in SIX.splitlines()]
    rows = "\n".join([
        '  { type = "prismatic", a = 100.0, d = 400.0, alpha = 0.0, theta = 0.0, lower = 0.0, '
        "upper = 350.0, velocity = 150.0, effort = 900.0 },", *lines[:5],
        '  { type = "prismatic", a = 0.0, d = 72.0, alpha = 0.0, theta = 0.0, lower = -20.0, '
        "upper = 30.0, velocity = 50.0, effort = 20.0 },"])
    robot = _model(tmp_path, 'parametrisation = "auto"', rows)
    assert robot.structure.joint_types == ("prismatic",) + ("revolute",) * 5 + ("prismatic",)
    assert robot.structure.parametrisation[0] == "hayati"  # the shoulder's axis is parallel
    np.testing.assert_allclose([robot.lower_rad[0], robot.upper_rad[0]], [0.0, 0.35])
    assert robot.velocity_rad_s is not None and robot.effort_nm is not None
    np.testing.assert_allclose([robot.velocity_rad_s[0], robot.effort_nm[0]], [0.15, 900.0])
    np.testing.assert_allclose(robot.upper_rad[1], np.deg2rad(165.0))
    text = robot_to_toml(robot)
    assert text.count('type = "prismatic"') == 2 and "upper = 350.0" in text
    path = tmp_path / "again.toml"
    path.write_text(text)
    back = load_robot(path)
    assert robot_to_toml(back) == text and back.structure.joint_types == robot.structure.joint_types
    q = np.random.default_rng(2).uniform(robot.lower_rad, robot.upper_rad, (50, 7))
    np.testing.assert_allclose(back.flange_transforms(q), robot.flange_transforms(q), atol=1e-9)
    assert robot.flange_positions(q[:1] + 0.1 * np.eye(7)[:1])[0, 2] \
        - robot.flange_positions(q[:1])[0, 2] == pytest.approx(0.1, abs=1e-12)
