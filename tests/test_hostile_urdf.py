"""Hostile inputs, class 6 — URDFs: one reading of the file, held to what a robot can be.

A URDF is read twice, by expat (the chain, its names and numbers) and by urdfdom inside
Pinocchio (the model). Whatever the two could read differently (a document type declaration,
whose entities only expat expands), whatever the chain walk could loop on (a cycle), whatever
numbers no arm has (a 5 km origin, ±100 rad limits, a zero axis), a chain joint that follows
another (``<mimic>``) and a file big enough to stall urdfdom are refused in one line naming
the file, the joint and the field, exit code 2, before anything is written. The cases that
crashed (rc −11) or hung run as processes with a timeout.
"""

from __future__ import annotations

from itertools import pairwise
from pathlib import Path

import numpy as np
import pytest
from conftest import Refusals

from twin.errors import InputError
from twin.io import urdf_reader
from twin.io.urdf_reader import MAX_URDF_BYTES, MAX_URDF_ELEMENTS, load_urdf

PORT = "600,-400,100"
TIMEOUT_S = 60.0
"""Far longer than a refusal takes, far shorter than a hang."""
LINKS = "abcdefg"


def _joint(name: str, parent: str, child: str, kind: str = "revolute", *,
           xyz: str = "0 0 0.1", rpy: str = "0.3 0 0", axis: str = "0 0 1",
           lower: str = "-1", upper: str = "1", extra: str = "") -> str:
    limit = (f'<limit lower="{lower}" upper="{upper}" effort="1" velocity="1"/>'
             if kind != "fixed" else "")
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/>'
            f'<child link="{child}"/><origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="{axis}"/>'
            f"{limit}{extra}</joint>")


def _urdf(changes: dict[int, dict[str, str]] | None = None, links: str | list[str] = LINKS,
          more: str = "", head: str = "") -> str:
    """A six-joint serial arm a → g (joints j0…j5), joint k given ``changes[k]``."""
    changes = changes or {}
    joints = "".join(_joint(f"j{k}", parent, child, **changes.get(k, {}))
                     for k, (parent, child) in enumerate(pairwise(links)))
    body = "".join(f'<link name="{name}"/>' for name in links)
    return f'{head}<robot name="arm">{body}{joints}{more}</robot>'


def _plan(refusals: Refusals, tmp_path: Path, text: str, match: str,
          process: bool = False) -> str:
    """`twin plan --robot arm.urdf …` refuses the file: one line, exit 2, nothing written;
    returns the line."""
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(text)
    out = tmp_path / "out"
    argv = ["plan", "--robot", urdf, "--port", PORT, "--poses", "30", "--joint-limits-only",
            "--out", out / "plan.csv"]
    error = refusals.process(argv, [urdf], f"{urdf}: {match}", timeout=TIMEOUT_S) \
        if process else refusals.cli(argv, [urdf], f"{urdf}: {match}")
    assert not out.exists()
    return error


DOCTYPE = '<?xml version="1.0"?>\n<!DOCTYPE robot [<!ENTITY name "{value}">]>\n'
NO_DOCTYPE = "found a document type declaration (<!DOCTYPE …>), expected a URDF file without one"


@pytest.mark.slow
def test_a_joint_named_through_an_entity(tmp_path: Path, refusals: Refusals) -> None:
    """Expat expands the entity, urdfdom does not: Pinocchio was asked for a joint it does not
    have and crashed (rc −11). The declaration is refused before either parser uses a name."""
    text = _urdf(head=DOCTYPE.format(value="j2")).replace('name="j2"', 'name="&name;"')
    _plan(refusals, tmp_path, text, NO_DOCTYPE, process=True)


@pytest.mark.slow
def test_a_tip_link_named_through_an_entity(tmp_path: Path, refusals: Refusals) -> None:
    """A tip link urdfdom names otherwise (it was an IndexError traceback)."""
    text = _urdf(head=DOCTYPE.format(value="tool0"), links=[*LINKS[:-1], "&name;"])
    _plan(refusals, tmp_path, text, NO_DOCTYPE, process=True)


def test_an_external_document_type(tmp_path: Path, refusals: Refusals) -> None:
    """A DOCTYPE naming an external DTD is refused the same way (nothing is fetched)."""
    _plan(refusals, tmp_path, _urdf(head='<!DOCTYPE robot SYSTEM "/etc/passwd">\n'), NO_DOCTYPE)


def test_names_the_two_parsers_read_apart(tmp_path: Path, refusals: Refusals) -> None:
    """A newline inside a name: expat normalises it to a space, urdfdom keeps it. The check
    that Pinocchio has every name of the chain refuses it instead of indexing with a missing
    id."""
    text = _urdf().replace('name="j2"', 'name="j\n2"')
    _plan(refusals, tmp_path, text, "found names Pinocchio does not read the same: joint 'j 2'")


def test_a_chain_pinocchio_reads_otherwise_is_refused(tmp_path: Path) -> None:
    """The numbers check: Pinocchio's chain at q = 0 against the XML's, both ways of being
    off (the tip moved by a micrometre, an axis turned)."""
    path = tmp_path / "arm.urdf"
    path.write_text(_urdf())
    root = urdf_reader._parse(path.read_text(), path)
    chain = urdf_reader.find_chain(root, None, None, path)
    fixed, _ = urdf_reader._fixed_transforms(urdf_reader._pinocchio_model(path.read_text(),
                                                                          path), chain)
    urdf_reader._check_same_chain(fixed, chain, path)  # as read: they agree
    moved = fixed.copy()
    moved[-1, 0, 3] += 1e-6
    turned = fixed.copy()
    turned[2, :3, :3] = turned[2, :3, :3] @ np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])
    for wrong in (moved, turned):
        with pytest.raises(InputError, match=r"found a chain Pinocchio reads .* away from the "
                           r"XML"):
            urdf_reader._check_same_chain(wrong, chain, path)


@pytest.mark.slow
def test_flange_and_tool0_each_others_parent(tmp_path: Path, refusals: Refusals) -> None:
    """The chain walk from tool0 went flange → tool0 → flange… for ever."""
    more = ('<link name="flange"/><link name="tool0"/>' + _joint("a", "flange", "tool0", "fixed")
            + _joint("b", "tool0", "flange", "fixed"))
    _plan(refusals, tmp_path, _urdf(more=more),
          "found a cycle of joints through link 'tool0', expected a tree", process=True)


def test_a_link_with_two_parents(tmp_path: Path, refusals: Refusals) -> None:
    _plan(refusals, tmp_path, _urdf(more=_joint("extra", "a", "d")),
          "found link 'd' the child of joints 'j2' and 'extra', expected one parent joint")


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"xyz": "1e308 0 0"}, "joint 'j2' <origin>: found xyz='1e308 0 0', expected three "
         "numbers within ±100 m"),
        ({"xyz": "5000 0 0"}, "joint 'j2' <origin>: found xyz='5000 0 0'"),
        ({"xyz": "-500 0 0"}, "joint 'j2' <origin>: found xyz='-500 0 0', expected three "
         "numbers within ±100 m"),
        ({"xyz": "0 1e20 0"}, "joint 'j2' <origin>: found xyz='0 1e20 0'"),
        ({"xyz": "nan 0 0"}, "joint 'j2' <origin>: found xyz='nan 0 0'"),
        ({"rpy": "1e10 0 0"}, "joint 'j2' <origin>: found rpy='1e10 0 0', expected three "
         "numbers within ±12.5664 rad (two turns)"),
        ({"lower": "-100", "upper": "100"}, "joint 'j2' <limit>: found lower='-100', expected "
         "a number within ±12.5664 rad (two turns)"),
        ({"lower": "0.5", "upper": "0.5"}, "joint 'j2' <limit>: found lower=0.5 >= upper=0.5"),
        ({"axis": "0 0 0"}, "joint 'j2' <axis>: found an axis of length 0, expected a "
         "direction"),
        ({"axis": "0 0 1e-9"}, "joint 'j2' <axis>: found an axis of length 1e-09"),
        ({"axis": "0 0"}, "joint 'j2' <axis>: found xyz='0 0', expected three finite numbers"),
        ({"axis": "0 inf 0"}, "joint 'j2' <axis>: found xyz='0 inf 0'"),
        ({"extra": '<mimic joint="j1" multiplier="1"/>'}, "joint 'j2': found a <mimic> joint "
         "on the chain (it follows 'j1'), expected independent joints"),
    ],
    ids=["1e308", "5 km", "500 m", "1e20", "nan", "rpy", "±100 rad", "empty range", "zero axis",
         "tiny axis", "two numbers", "infinite axis", "mimic"],
)
def test_numbers_no_arm_has(change: dict[str, str], match: str, tmp_path: Path,
                            refusals: Refusals) -> None:
    """The model file's plausibility checks hold for a URDF's numbers too, naming the joint
    and the field (they were an IndexError in identifiability.py, numpy warnings and an
    unnamed error, or accepted with only a MISFIT line)."""
    _plan(refusals, tmp_path, _urdf({2: change}), match)


def test_an_off_chain_origin_no_arm_has(tmp_path: Path, refusals: Refusals) -> None:
    """Every joint Pinocchio composes is held to it, off the chain too (a gripper finger)."""
    more = '<link name="finger"/>' + _joint("finger_joint", "f", "finger", "prismatic",
                                            xyz="0 5e3 0")
    _plan(refusals, tmp_path, _urdf(links=[*LINKS[:-1], "tool0"], more=more),
          "joint 'finger_joint' <origin>: found xyz='0 5e3 0'")


def test_a_mimic_joint_off_the_chain_is_kept(tmp_path: Path) -> None:
    """A gripper's mimic finger is left at zero, as every off-chain joint: not refused; an
    axis that is not of unit length is normalised (as urdfdom does)."""
    more = ('<link name="l"/><link name="r"/>'
            + _joint("left", "g", "l", "prismatic", lower="0", upper="0.04")
            + _joint("right", "g", "r", "prismatic", lower="0", upper="0.04",
                     extra='<mimic joint="left"/>'))
    path = tmp_path / "arm.urdf"
    path.write_text(_urdf({2: {"axis": "0 0 5"}}, more=more))
    robot = load_urdf(path, tip_link="g")
    path.write_text(_urdf(more=more))
    np.testing.assert_allclose(robot.dh, load_urdf(path, tip_link="g").dh, atol=1e-12)


def test_an_attribute_is_quoted_short(tmp_path: Path, refusals: Refusals) -> None:
    """An error quotes the field it refuses, not a megabyte of it."""
    error = _plan(refusals, tmp_path, _urdf({2: {"xyz": "1 " * 100_000}}),
                  "joint 'j2' <origin>: found xyz='1 1 1 ")
    assert len(error) < 300


@pytest.mark.slow
def test_a_urdf_too_big_for_pinocchio(tmp_path: Path, refusals: Refusals) -> None:
    """urdfdom's parse grows quadratically with the links (10 000: 3.6 s, 40 000: 53 s) and a
    chain 4000 deep overflows its stack: more than MAX_URDF_ELEMENTS links, or joints, or a
    file over MAX_URDF_BYTES, is refused before Pinocchio parses it."""
    count = MAX_URDF_ELEMENTS + 1
    off_chain = "".join(f'<link name="x{i}"/>' for i in range(count))
    _plan(refusals, tmp_path, _urdf(more=off_chain),
          f"found {count + len(LINKS)} <link> elements, expected a URDF file of at most "
          f"{MAX_URDF_ELEMENTS}", process=True)
    joints = "".join(_joint(f"x{i}", "g", f"x{i}", "fixed") for i in range(count))
    _plan(refusals, tmp_path, _urdf(more=joints),
          f"found {count + len(LINKS) - 1} <joint> elements")
    text = "<!--" + "x" * MAX_URDF_BYTES + "-->" + _urdf()
    _plan(refusals, tmp_path, text, f"found {len(text)} bytes, expected a URDF file of at "
          f"most {MAX_URDF_BYTES} bytes", process=True)


def test_a_urdf_robot_of_a_scenario(tmp_path: Path, refusals: Refusals) -> None:
    """Through a scenario (it was a MuJoCo mjMINVAL traceback): the same line."""
    (tmp_path / "arm.urdf").write_text(_urdf({2: {"xyz": "1e308 0 0"}}))
    scenario = tmp_path / "s.toml"
    scenario.write_text('name = "s"\nseed = 1\nrobot = "arm.urdf"\n[port]\n'
                        "position_mm = [600.0, -400.0, 100.0]\n[poses]\ncount = 30\n")
    refusals.cli(["simulate", scenario, "--out", tmp_path / "out"],
                 [scenario, tmp_path / "arm.urdf"],
                 f"{tmp_path / 'arm.urdf'}: joint 'j2' <origin>: found xyz='1e308 0 0'")
    assert not (tmp_path / "out").exists()
