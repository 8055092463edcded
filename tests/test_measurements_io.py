"""Measurement CSV files: exact round trip and one clear error per kind of mistake."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from twin.dataset import Measurements
from twin.errors import InputError
from twin.io.measurements import UnitWarning, load_measurements, write_measurements
from twin.robot import RobotModel

HEADER = "q1,q2,q3,q4,q5,q6,length\n"
ROW = "10,20,-30,40,-50,60,812.5\n"


def test_round_trip_is_exact(measurements: Measurements, tmp_path: Path) -> None:
    """Writing then reading gives the same lengths to 1e-12 m and angles to 1e-15 rad."""
    path = tmp_path / "m.csv"
    write_measurements(path, measurements)
    back = load_measurements(path)
    np.testing.assert_allclose(back.q_rad, measurements.q_rad, rtol=0, atol=1e-15)
    np.testing.assert_allclose(back.length_m, measurements.length_m, rtol=0, atol=1e-12)


def test_extra_columns_comments_and_order(tmp_path: Path) -> None:
    """Other columns are ignored, columns may come in any order, comments are skipped."""
    path = tmp_path / "m.csv"
    path.write_text("# captured by hand\npose,length,q1,q2,q3,q4,q5,q6,note\n"
                    "1,812.5,10,20,-30,40,-50,60,ok\n")
    data = load_measurements(path)
    assert data.length_m[0] == pytest.approx(0.8125)
    np.testing.assert_allclose(np.rad2deg(data.q_rad[0]), [10, 20, -30, 40, -50, 60])


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (b"", "found an empty file"),
        (HEADER.encode(), "found a header and no data rows"),
        (b"q1,q2,q3,q4,q5,length\n1,2,3,4,5,6\n", "(no q6)"),
        ((HEADER + "1,2,3,4,5,6\n").encode(), "line 2: found 6 fields, expected 7"),
        ((HEADER + "1,2,3,4,5,6,7,8\n").encode(), "line 2: found 8 fields"),
        ((HEADER + "1,2,x,4,5,6,7\n").encode(), "line 2, column q3: found 'x', expected a number"),
        ((HEADER + "1,2,3,4,5,6,nan\n").encode(), "column length: found 'nan', expected a finite"),
        ((HEADER + "1,2,3,4,5,inf,7\n").encode(), "column q6: found 'inf'"),
        ((HEADER + "1,2,3,4,5,6,-7\n").encode(), "found -7 mm, expected a positive cable"),
        (b"\x89PNG\r\n\x1a\n\x00\x00binary", "found binary data"),
        (b"q1,q2\xff\xfe", "not UTF-8"),
        (b"q1,q1,q2,q3,q4,q5,q6,length\n1,1,2,3,4,5,6,7\n", "column 'q1' twice"),
    ],
)
def test_bad_files(tmp_path: Path, content: bytes, message: str) -> None:
    """Each mistake is one InputError naming the file and what was found."""
    path = tmp_path / "bad.csv"
    path.write_bytes(content)
    with pytest.raises(InputError) as info:
        load_measurements(path)
    assert str(info.value).startswith(str(path)) and message in str(info.value)


def test_joint_outside_limits(irb120: RobotModel, tmp_path: Path) -> None:
    """A joint beyond the robot's limits names the line, the column and the limits."""
    path = tmp_path / "m.csv"
    path.write_text(HEADER + ROW + "0,0,75,0,0,0,800\n")
    with pytest.raises(InputError, match=r"line 3, column q3: found 75 deg, expected within "
                                         r"\[-110, 70\] deg"):
        load_measurements(path, irb120)


def test_radians_in_degree_columns_warn(tmp_path: Path) -> None:
    """Angles that all fit within ±2π look like radians: a warning, not an error."""
    path = tmp_path / "m.csv"
    path.write_text(HEADER + "0.1,0.5,-1.2,0.3,1.5,-2.0,800\n" * 4)
    with pytest.warns(UnitWarning, match="radians"):
        load_measurements(path)
