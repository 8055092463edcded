"""A user's mistakes with rigs: each is one line on stderr, exit code 2, nothing written."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import Refusals

from twin.io.measurements import write_measurements
from twin.io.robot_file import default_robot, robot_to_toml
from twin.kinds.plane import plane_measurements
from twin.kinds.point import point_measurements
from twin.kinds.position import position_measurements
from twin.robot import RobotModel, random_poses

PORT = "600,-400,100"


@pytest.fixture()
def tracker_csv(tmp_path: Path, irb120: RobotModel) -> Path:
    """A tracker measurement CSV of 40 poses."""
    q = random_poses(irb120, 40, np.random.default_rng(0))
    path = tmp_path / "tracker.csv"
    write_measurements(path, position_measurements(q, irb120.flange_positions(q)))
    return path


@pytest.mark.parametrize(("flags", "match"), [
    (["--port", "front=600,-400"], "--port: found '600,-400', expected three finite numbers"),
    (["--port", "front=1,2,3", "--port", "4,5,6"], "--port: found 2 ports, 1 without a name"),
    (["--port", "a=1,2,3", "--port", "a=4,5,6"], "--port: found a port name twice"),
    (["--port", PORT, "--estimate-port", "left"], "--estimate-port: found unknown port 'left'"),
    (["--port", PORT, "--distance", "a,b"], "--distance: found 'a,b', expected A,B=MM"),
    (["--port", PORT, "--distance", "a,a=50"], "expected A,B=MM: two different point names"),
    (["--port", PORT, "--angle", "a,b=0.5"], "--angle: found 'a,b=0.5', expected A,B=DEG: two "
     "different plane names and the angle between their normals, 1 to 179 degrees"),
    (["--port", PORT, "--angle", "a,b=90", "--angle", "b,a=89"],
     "--angle: found b,a a second time (90 deg, then 89 deg), expected each pair of planes once"),
    (["--port", PORT, "--attachment", "1,2"], "--attachment: found '1,2'"),
    (["--port", PORT, "--loss", "hubber"], "--loss: found 'hubber', expected one of linear, "
     "huber"),
    (["--port", PORT, "--loss-scale", "0"], "--loss-scale: found '0'"),
])
def test_bad_rig_flags(flags: list[str], match: str, csv_path: Path,
                       refusals: Refusals) -> None:
    """Malformed ports, distances, attachments and losses are refused where they are parsed."""
    refusals.cli(["calibrate", csv_path, *flags], [csv_path.parent], match)


def test_unknowns_the_data_cannot_have(tracker_csv: Path, refusals: Refusals) -> None:
    """Tracker positions have no port to estimate; a distance must join points the data name."""
    refusals.cli(["calibrate", tracker_csv, "--estimate-port"], [tracker_csv.parent],
                 "found --estimate-port with position measurements, expected only the unknowns "
                 "they can have: --estimate-attachment, --estimate-base")


def test_a_distance_to_a_point_the_data_do_not_name(tmp_path: Path, irb120: RobotModel,
                                                     refusals: Refusals) -> None:
    """--distance between names the point column does not have is refused, naming them."""
    q = random_poses(irb120, 40, np.random.default_rng(1))
    path = tmp_path / "points.csv"
    write_measurements(path, point_measurements(q, np.arange(40) % 2, point_names=("a", "b")))
    refusals.cli(["calibrate", path, "--distance", "a,c=50"], [tmp_path],
                 "--distance: found a distance to the point 'c', expected distances between "
                 "points the measurements name: a, b")


def test_an_angle_to_a_plane_the_data_do_not_name(tmp_path: Path, irb120: RobotModel,
                                                  refusals: Refusals) -> None:
    """--angle between names the plane column does not have is refused, naming them."""
    q = random_poses(irb120, 40, np.random.default_rng(1))
    path = tmp_path / "planes.csv"
    write_measurements(path, plane_measurements(q, np.arange(40) % 2, plane_names=("a", "b")))
    refusals.cli(["calibrate", path, "--angle", "a,c=90"], [tmp_path],
                 "--angle: found an angle to the plane 'c', expected angles between planes the "
                 "measurements name: a, b")


def test_a_capture_with_both_port_forms(tmp_path: Path, csv_path: Path,
                                        refusals: Refusals) -> None:
    """capture.toml with port_mm and [ports] is refused, naming both."""
    (tmp_path / "robot.toml").write_text(robot_to_toml(default_robot()))
    capture = tmp_path / "capture.toml"
    capture.write_text('robot = "robot.toml"\nport_mm = [600.0, -400.0, 100.0]\n'
                       f'measurements = "{csv_path.name}"\n[ports]\nfront = [1.0, 2.0, 3.0]\n')
    refusals.cli(["calibrate", capture], [tmp_path], "found both port_mm and [ports]")
