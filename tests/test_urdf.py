"""URDF in: a URDF's chain becomes a robot whose forward kinematics is Pinocchio's."""

from __future__ import annotations

from itertools import pairwise
from pathlib import Path

import numpy as np
import pytest

from twin.cli import main
from twin.errors import InputError
from twin.export.pinocchio import urdf_flange
from twin.io.robot_file import default_robot, load_robot
from twin.io.urdf_reader import CONTINUOUS_LIMIT_RAD, load_urdf
from twin.robot import RobotModel

MODELS = Path(__file__).resolve().parents[1] / "models"
URDFS = {"ur5e": MODELS / "ur5e" / "ur5e.urdf", "fr3": MODELS / "fr3" / "fr3.urdf",
         "irb120": MODELS / "irb120" / "irb120_3_58.urdf",
         "fr3_torso": MODELS / "fr3_torso" / "fr3_torso.urdf"}


def _pinocchio(robot: RobotModel, q: np.ndarray) -> np.ndarray:
    assert robot.urdf is not None
    return urdf_flange(robot.urdf.text, robot.joint_names, q, robot.urdf.tip_link,
                       robot.urdf.base_link)


@pytest.mark.parametrize("request_", ["auto", "dh", "mdh"])
@pytest.mark.parametrize("name", list(URDFS))
def test_fk_equals_pinocchio(name: str, request_: str) -> None:
    """Each shipped URDF in each parametrisation (the torso's prismatic lift among them, q in m):
    the flange pose equals Pinocchio's pose of the tip link in the base link to 1e-9 m (and 1e-9
    in rotation) over 1000 random poses."""
    robot = load_urdf(URDFS[name], parametrisation=request_)
    q = np.random.default_rng(0).uniform(robot.lower_rad, robot.upper_rad,
                                         (1000, robot.n_joints))
    found = robot.flange_transforms(q)
    np.testing.assert_allclose(found, _pinocchio(robot, q), rtol=0.0, atol=1e-9)


def test_defaults_names_limits_and_choice() -> None:
    """The UR5e: the chain runs from the root (world) to tool0; the joints keep their names,
    limits, rated speeds and torques; auto makes joints 2 and 3 Hayati (axes 2, 3, 4
    parallel); link masses come from the inertials."""
    robot = load_robot(URDFS["ur5e"])
    assert robot.urdf is not None and robot.name == "ur5e"
    assert (robot.urdf.base_link, robot.urdf.tip_link) == ("world", "tool0")
    assert robot.joint_names == ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint",
                                 "wrist_1_joint", "wrist_2_joint", "wrist_3_joint")
    assert robot.structure.parametrisation == ("dh", "hayati", "hayati", "dh", "dh", "dh")
    np.testing.assert_allclose(robot.upper_rad, [2 * np.pi] * 2 + [np.pi] + [2 * np.pi] * 3)
    assert robot.effort_nm is not None and robot.velocity_rad_s is not None
    np.testing.assert_allclose(robot.effort_nm, [150.0] * 3 + [28.0] * 3)
    np.testing.assert_allclose(robot.velocity_rad_s, np.pi)
    assert robot.mass_kg is not None
    np.testing.assert_allclose(robot.mass_kg, [3.761, 8.058, 2.846, 1.37, 1.3, 0.365])


def test_irb120_urdf_is_the_paper_table() -> None:
    """ROS-Industrial's IRB 120 read as standard D-H is the paper's table (θ6 = 180°: ROS-I's
    tool0) and puts the flange centre where the model file does."""
    robot = load_urdf(URDFS["irb120"], parametrisation="dh")
    paper = default_robot()
    expected = paper.dh.copy()
    expected[3, 5] = np.pi
    np.testing.assert_allclose(robot.dh, expected, rtol=0.0, atol=1e-12)
    q = np.random.default_rng(1).uniform(paper.lower_rad, paper.upper_rad, (200, 6))
    np.testing.assert_allclose(robot.flange_positions(q), paper.flange_positions(q), atol=1e-12)


def test_base_and_tip_links_choose_the_chain() -> None:
    """--base-link and --tip-link pick another piece of the tree: from base_link (below
    world) to flange (before tool0), Pinocchio's pose of flange in base_link."""
    robot = load_robot(URDFS["ur5e"], base_link="base_link", tip_link="flange")
    assert robot.urdf is not None and robot.urdf.tip_link == "flange"
    q = np.random.default_rng(2).uniform(-np.pi, np.pi, (100, 6))
    np.testing.assert_allclose(robot.flange_transforms(q), _pinocchio(robot, q), atol=1e-9)


def _write(tmp_path: Path, joints: str, links: str = "abcdef") -> Path:
    body = "".join(f'<link name="{name}"/>' for name in links)
    path = tmp_path / "arm.urdf"
    path.write_text(f'<robot name="arm">{body}{joints}</robot>')
    return path


def _joint(name: str, parent: str, child: str, kind: str = "revolute",
           axis: str = "0 0 1", xyz: str = "0 0 0.1") -> str:
    limit = '<limit lower="-1" upper="1" effort="1" velocity="1"/>' if kind != "fixed" else ""
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/>'
            f'<child link="{child}"/><origin xyz="{xyz}" rpy="0.3 0 0"/><axis xyz="{axis}"/>'
            f"{limit}</joint>")


def _serial(links: str, other: int | None = None, kind: str = "prismatic") -> str:
    """Revolute joints j0, j1… linking each link to the next (joint ``other`` of ``kind``)."""
    return "".join(_joint(f"j{i}", parent, child, kind if i == other else "revolute")
                   for i, (parent, child) in enumerate(pairwise(links)))


def test_continuous_joints_and_any_axis(tmp_path: Path) -> None:
    """A continuous joint gets limits of ±180°; axes along y, −x or askew are turned onto z
    exactly (FK equal to Pinocchio's)."""
    joints = (_joint("j1", "a", "b", axis="0 1 0") + _joint("j2", "b", "c", "continuous",
                                                            axis="-1 0 0")
              + _joint("j3", "c", "d", axis="0 0.6 0.8")
              + _joint("j4", "d", "e", "continuous", axis="0 -1 0") + _joint("f", "e", "f",
                                                                            "fixed"))
    robot = load_urdf(_write(tmp_path, joints))
    assert robot.n_joints == 4 and robot.urdf is not None and robot.urdf.tip_link == "f"
    np.testing.assert_allclose(robot.upper_rad[[1, 3]], CONTINUOUS_LIMIT_RAD)
    q = np.random.default_rng(3).uniform(-1.0, 1.0, (200, 4))
    np.testing.assert_allclose(robot.flange_transforms(q), _pinocchio(robot, q), atol=1e-9)


@pytest.mark.parametrize(
    ("joints", "links", "flags", "message"),
    [
        (_joint("j1", "a", "b") + _joint("j2", "b", "c"), "abc", {}, "2 moving joints"),
        (_serial("abcdefghijkl"), "abcdefghijkl", {}, "11 moving joints from 'a' to 'l', "
         "expected 4 to 9"),
        (_serial("abcde"), "abcde", {"tip_link": "zz"}, "--tip-link 'zz'"),
        (_serial("abcde"), "abcde", {"base_link": "c", "tip_link": "b"}, "not below base link"),
        (_serial("abcdef", 2, "planar"), "abcdef", {}, "of type 'planar' on the chain, "
         "expected revolute, continuous, prismatic or fixed joints only"),
        ("".join(_joint(f"j{i}", "a", y) for i, y in enumerate("bcdef")), "abcdef", {},
         "several leaf links"),
    ],
)
def test_bad_chains_are_named(tmp_path: Path, joints: str, links: str, flags: dict[str, str],
                              message: str) -> None:
    """Too few or too many joints, an unknown link, a tip not below the base, a planar joint
    on the chain, several leaves and no tool0: one InputError naming the file and the
    problem."""
    path = _write(tmp_path, joints, links)
    with pytest.raises(InputError) as info:
        load_urdf(path, **flags)
    assert str(path) in str(info.value) and message in str(info.value)


def test_prismatic_joints_slide_in_metres(tmp_path: Path) -> None:
    """Prismatic joints along any axis (z, −y, askew) read as sliding joints: their limits in
    m (a limit beyond 100 m refused), FK equal to Pinocchio's, the torso's lift a prismatic
    Hayati joint (the arm's first axis parallel to it) with the rated speed and force."""
    joints = (_joint("j1", "a", "b", "prismatic") + _joint("j2", "b", "c")
              + _joint("j3", "c", "d", "prismatic", axis="0 -1 0")
              + _joint("j4", "d", "e") + _joint("j5", "e", "f", "prismatic", axis="0.6 0 0.8"))
    robot = load_urdf(_write(tmp_path, joints))
    assert robot.structure.joint_types == ("prismatic", "revolute", "prismatic", "revolute",
                                           "prismatic")
    np.testing.assert_array_equal(robot.prismatic, [True, False, True, False, True])
    q = np.random.default_rng(4).uniform(robot.lower_rad, robot.upper_rad, (200, 5))
    np.testing.assert_allclose(robot.flange_transforms(q), _pinocchio(robot, q), atol=1e-9)
    torso = load_urdf(URDFS["fr3_torso"])
    assert torso.structure.parametrisation[0] == "hayati"
    assert torso.structure.joint_types == ("prismatic",) + ("revolute",) * 7
    assert (torso.lower_rad[0], torso.upper_rad[0]) == (0.0, 0.4)
    assert torso.velocity_rad_s is not None and torso.effort_nm is not None
    assert (torso.velocity_rad_s[0], torso.effort_nm[0]) == (0.1, 1000.0)
    far = _write(tmp_path, joints.replace('upper="1"', 'upper="101"', 1))
    with pytest.raises(InputError, match=r"upper=.101.*within ±100 m"):
        load_urdf(far)


def test_urdf_pinocchio_refuses_is_one_line(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    """A URDF urdfdom refuses (a limit without effort) is one line on stderr with urdfdom's
    reason, exit code 2, nothing of urdfdom's own console output."""
    path = _write(tmp_path, _serial("abcdef").replace(' effort="1"', "", 1))
    code = main(["calibrate", str(tmp_path / "m.csv"), "--robot", str(path), "--port", "1,1,1"])
    error = capsys.readouterr().err
    assert code == 2 and error.count("\n") == 1
    assert error.startswith(f"twin: error: {path}: found a URDF Pinocchio cannot read (")
    assert "effort" in error
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot><link")
    assert main(["plan", "--robot", str(bad), "--port", "1,1,1", "--poses", "30",
                 "--out", str(tmp_path / "plan.csv")]) == 2
    assert "found invalid XML" in capsys.readouterr().err
