"""Measurement CSV files: exact round trip and one clear error per kind of mistake."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from twin.dataset import Measurements
from twin.errors import InputError
from twin.io.measurements import UnitWarning, load_measurements, write_measurements
from twin.kinds.length import length_measurements
from twin.kinds.point import point_measurements
from twin.kinds.position import position_measurements
from twin.robot import RobotModel

HEADER = "q1,q2,q3,q4,q5,q6,length\n"
ROW = "10,20,-30,40,-50,60,812.5\n"


def test_round_trip_is_exact(measurements: Measurements, tmp_path: Path) -> None:
    """Writing then reading gives the same lengths to 1e-12 m and angles to 1e-15 rad."""
    path = tmp_path / "m.csv"
    write_measurements(path, measurements)
    back = load_measurements(path)
    np.testing.assert_allclose(back.q_rad, measurements.q_rad, rtol=0, atol=1e-15)
    np.testing.assert_allclose(back.value("length_m"), measurements.value("length_m"), rtol=0,
                               atol=1e-12)


def test_extra_columns_comments_and_order(tmp_path: Path) -> None:
    """Other columns are ignored, columns may come in any order, comments are skipped."""
    path = tmp_path / "m.csv"
    path.write_text("# captured by hand\npose,length,q1,q2,q3,q4,q5,q6,note\n"
                    "1,812.5,10,20,-30,40,-50,60,ok\n")
    data = load_measurements(path)
    assert data.value("length_m")[0] == pytest.approx(0.8125)
    np.testing.assert_allclose(np.rad2deg(data.q_rad[0]), [10, 20, -30, 40, -50, 60])


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (b"", "found an empty file"),
        (HEADER.encode(), "found a header and no data rows"),
        (b"q1,q2,q3,q4,q5,length\n1,2,3,4,5,6\n", "line 1: found a header without q6"),
        ((HEADER + "1,2,3,4,5,6\n").encode(), "line 2: found 6 fields, expected 7"),
        ((HEADER + "1,2,3,4,5,6,7,8\n").encode(), "line 2: found 8 fields"),
        ((HEADER + "1,2,x,4,5,6,7\n").encode(), "line 2, column q3: found 'x', expected a number"),
        ((HEADER + "1,2,3,4,5,6,nan\n").encode(), "column length: found 'nan', expected a finite"),
        ((HEADER + "1,2,3,4,5,inf,7\n").encode(), "column q6: found 'inf'"),
        ((HEADER + "1,2,3,4,5,6,-7\n").encode(), "found -7 mm, expected a positive cable"),
        (b"\x89PNG\r\n\x1a\n\x00\x00binary", "found binary data"),
        (b"q1,q2\xff\xfe", "not UTF-8"),
        (b"q1,q1,q2,q3,q4,q5,q6,length\n1,1,2,3,4,5,6,7\n", "column 'q1' twice"),
        (b"q1;q2;q3;q4;q5;q6;length\n1;2;3;4;5;6;1.234,5\n",
         "line 2, column length: found '1.234,5', expected a number (a decimal comma or point)"),
    ],
)
def test_bad_files(tmp_path: Path, content: bytes, message: str) -> None:
    """Each mistake is one InputError naming the file and what was found."""
    path = tmp_path / "bad.csv"
    path.write_bytes(content)
    with pytest.raises(InputError) as info:
        load_measurements(path)
    assert str(info.value).startswith(str(path)) and message in str(info.value)


@pytest.mark.parametrize(("first", "delimiter"), [("", ";"), ("", "\t"), ("sep=;\n", ";")])
def test_a_spreadsheets_export_reads_as_the_comma_file(tmp_path: Path, first: str,
                                                       delimiter: str) -> None:
    """Fields separated by semicolons or tabs, numbers with a decimal comma or point (as a
    spreadsheet exports where the decimal mark is a comma), after Excel's sep= line or not:
    the same measurements as the comma file of the same numbers."""
    comma = tmp_path / "comma.csv"
    comma.write_text(HEADER + ROW + "-10.25,0,5,0,30.5,-60,640\n")
    local = tmp_path / "local.csv"
    local.write_text("# from a spreadsheet\n" + first
                     + delimiter.join(HEADER.strip().split(",")) + "\n"
                     + delimiter.join(["10", "20", "-30", "40", "-50", "60", "812,5"]) + "\n"
                     + delimiter.join(["-10,25", "0", "5", "0", "30.5", "-60", "640"]) + "\n")
    read, expected = load_measurements(local), load_measurements(comma)
    np.testing.assert_array_equal(read.q_rad, expected.q_rad)
    np.testing.assert_array_equal(read.value("length_m"), expected.value("length_m"))


def test_joint_outside_limits(irb120: RobotModel, tmp_path: Path) -> None:
    """A joint beyond the robot's limits names the line, the column and the limits."""
    path = tmp_path / "m.csv"
    path.write_text(HEADER + ROW + "0,0,75,0,0,0,800\n")
    with pytest.raises(InputError, match=r"line 3, column q3: found 75 deg, expected within "
                                         r"\[-110, 70\] deg"):
        load_measurements(path, irb120)


def _rows(q: np.ndarray) -> str:
    return HEADER + "".join(",".join(f"{v:.6f}" for v in row) + ",800\n" for row in q)


def test_radians_in_degree_columns_warn(tmp_path: Path, irb120: RobotModel) -> None:
    """Joint columns written in radians are named, per column: the IRB 120's q6 wound to
    6.9 rad (beyond 2π, inside its ±400° limits) is one of them with the robot's limits, and
    without a robot (±2π) it does not hide q1..q5; the hint names the converter."""
    rng = np.random.default_rng(4)
    q = rng.uniform(0.9 * irb120.lower_rad, 0.9 * irb120.upper_rad, (20, 6))
    q[0, 5] = 0.99 * irb120.upper_rad[5]
    assert q[0, 5] > 2 * np.pi
    path = tmp_path / "m.csv"
    path.write_text(_rows(q))
    with pytest.warns(UnitWarning, match=r"the columns q1, q2, q3, q4, q5, q6 span .* "
                                         r"--angle-unit rad"):
        load_measurements(path, irb120)
    with pytest.warns(UnitWarning, match=r"the columns q1, q2, q3, q4, q5 span"):
        load_measurements(path)


def test_degrees_with_narrow_joints_do_not_warn(tmp_path: Path, irb120: RobotModel) -> None:
    """Degrees with one or two joints barely moved (a wrist held within ±2°, a fixed q6)
    read without a unit warning: a narrow joint is not a unit."""
    rng = np.random.default_rng(5)
    q_deg = np.rad2deg(rng.uniform(0.9 * irb120.lower_rad, 0.9 * irb120.upper_rad, (20, 6)))
    q_deg[:, 4] = rng.uniform(-2.0, 2.0, 20)
    q_deg[:, 5] = 0.0
    path = tmp_path / "m.csv"
    path.write_text(_rows(q_deg))
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnitWarning)
        load_measurements(path, irb120)


def test_approach_directions_are_plus_or_minus_one_exactly() -> None:
    """Approach directions are labels: ±1 as integers, floats or booleans' True are taken
    (as int8), anything else — 0, 2, 0.5, NaN, an imaginary unit — is refused."""
    q = np.zeros((2, 6))
    for good in (np.ones((2, 6), dtype=int), -np.ones((2, 6)), np.ones((2, 6), dtype=bool)):
        taken = length_measurements(q, np.ones(2), approach=good).approach
        assert taken is not None and taken.dtype == np.int8
        np.testing.assert_array_equal(taken, good.astype(np.int8))
    for wrong in (0.0, 2.0, 0.5, np.nan, 1j):
        approach = np.ones((2, 6), dtype=complex if wrong == 1j else float)
        approach[1, 3] = wrong
        with pytest.raises(ValueError, match="labels \\+1 or -1"):
            length_measurements(q, np.ones(2), approach=approach)


@pytest.mark.parametrize("kind", ["length", "length+ports", "position", "point"])
def test_every_kind_round_trips_with_approach_columns(tmp_path: Path, kind: str) -> None:
    """Lengths (with named ports), tracker positions and fixed-point names, with approach
    directions, are written and read back to the same values and labels."""
    rng = np.random.default_rng(3)
    q = rng.uniform(-1.0, 1.0, (5, 6))
    approach = rng.choice([-1, 1], (5, 6))
    if kind.startswith("length"):
        ports = dict(port=np.array([0, 1, 1, 0, 1]), port_names=("front", "back")) \
            if kind.endswith("ports") else {}
        data = length_measurements(q, rng.uniform(0.5, 1.0, 5), approach=approach, **ports)
    elif kind == "position":
        data = position_measurements(q, rng.normal(size=(5, 3)), approach=approach)
    else:
        data = point_measurements(q, np.array([0, 0, 1, 2, 1]), approach=approach,
                                  point_names=("A", "B", "C"))
    path = tmp_path / "m.csv"
    write_measurements(path, data)
    loaded = load_measurements(path)
    assert loaded.kind == data.kind
    np.testing.assert_allclose(loaded.q_rad, data.q_rad, rtol=1e-15)
    np.testing.assert_array_equal(loaded.approach, approach)
    assert set(loaded.values) == set(data.values)
    for name, column in data.values.items():
        np.testing.assert_allclose(loaded.value(name), column, rtol=1e-15)
    if "port" in data.labels:
        assert loaded.labels["port"].per_row() == data.labels["port"].per_row()
    if "point" in data.labels:
        assert loaded.labels["point"].per_row() == ["A", "A", "B", "C", "B"]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("q1,q2,q3,q4,q5,q6,length,x,y,z\n" + "0,0,0,0,0,0,700,1,2,3\n",
         "line 1: found columns q1,q2,q3,q4,q5,q6,length,x,y,z, expected exactly one of"),
        ("q1,q2,q3,q4,q5,q6,x,y\n0,0,0,0,0,0,1,2\n", "expected exactly one of length"),
        ("q1,q2,q3,q4,q5,q6,length,approach1\n0,0,0,0,0,0,700,1\n",
         "found no approach2,approach3,approach4,approach5,approach6, expected all of"),
        ("q1,q2,q3,q4,q5,q6,length,approach1,approach2,approach3,approach4,approach5,approach6\n"
         "0,0,0,0,0,0,700,1,1,1,0,1,1\n", "line 2, column approach4: found 0, expected +1 or -1"),
        ("q1,q2,q3,q4,q5,q6,x,y,z,port\n0,0,0,0,0,0,1,2,3,a\n",
         "found a port column, expected port only beside length"),
        ("q1,q2,q3,q4,q5,q6,point\n0,0,0,0,0,0, \n",
         "line 2, column point: found '', expected a name of 1 to 64 characters"),
    ],
)
def test_kind_and_option_columns_are_checked(tmp_path: Path, text: str, message: str) -> None:
    """A file with no or two kinds, half the approach columns, a bad direction, a port on a
    tracker row or an empty name is one clear error."""
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(InputError, match=re.escape(message)):
        load_measurements(path)


def test_a_prismatic_joint_is_in_mm(tmp_path: Path) -> None:
    """For a robot with a prismatic joint, its column is in mm in every file (measurements,
    plans, poses), the others in degrees: a written file says 250 for 0.25 m and reads back
    exactly; its limits are checked and reported in mm; the ±2π unit warning looks at the
    angles alone."""
    from twin.io.measurements import load_plan, load_poses
    from twin.io.robot_file import load_robot

    robot = load_robot(Path(__file__).resolve().parents[1] / "models" / "fr3_torso"
                       / "fr3_torso.urdf")
    q = np.random.default_rng(0).uniform(robot.lower_rad, robot.upper_rad, (5, 8))
    q[0, 0] = 0.25
    data = length_measurements(q, np.full(5, 1.2))
    path = tmp_path / "m.csv"
    write_measurements(path, data, robot)
    first = path.read_text().splitlines()[1].split(",")
    assert first[0] == "250.0" and float(first[1]) == pytest.approx(np.rad2deg(q[0, 1]))
    back = load_measurements(path, robot)
    np.testing.assert_allclose(back.q_rad, q, rtol=0, atol=1e-15)
    np.testing.assert_allclose(load_plan(path, robot)[0], q, rtol=0, atol=1e-15)
    np.testing.assert_allclose(load_poses(path, robot, "poses").q_rad, q, rtol=0, atol=1e-15)
    text = path.read_text().splitlines()
    path.write_text("\n".join([text[0], "450," + text[1].split(",", 1)[1], *text[2:]]) + "\n")
    with pytest.raises(InputError, match=r"line 2, column q1: found 450 mm, expected within "
                       r"\[0, 400\] mm \(joint 1 of fr3_torso\)"):
        load_measurements(path, robot)
