"""Flags the data cannot use are refused in one line naming the flag and why, not ignored; a
known distance is blamed on where it came from."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from conftest import Refusals

from twin.calibration.setup import make_model
from twin.io.capture_file import write_capture
from twin.io.measurements import write_measurements
from twin.io.robot_file import robot_to_toml
from twin.rig import Distance, Rig
from twin.robot import RobotModel, random_poses


def _tracker_csv(irb120: RobotModel, folder: Path) -> Path:
    """Tracker positions of 60 poses, the tracker frame at the base."""
    q = random_poses(irb120, 60, np.random.default_rng(4))
    data = make_model(irb120, Rig(), "position").measure(np.zeros(24), q)
    path = folder / "tracker.csv"
    write_measurements(path, data)
    return path


def test_flags_for_other_data(irb120: RobotModel, csv_path: Path, tmp_path: Path,
                              refusals: Refusals) -> None:
    """--port with tracker positions, --distance with cable lengths, --sigma-deg without
    orientations, --loss-scale without a robust loss, --tolerance without --baseline: each
    refused, naming the flag."""
    tracker = _tracker_csv(irb120, tmp_path)
    refusals.cli(["calibrate", tracker, "--port", "600,-400,100"], [tracker],
                 "--port: found --port with position measurements, expected --port only with "
                 "cable lengths")
    refusals.cli(["calibrate", csv_path, "--port", "600,-400,100", "--distance", "a,b=50"],
                 [csv_path], "--distance: found --distance with length measurements")
    refusals.cli(["calibrate", csv_path, "--port", "600,-400,100", "--angle", "a,b=90"],
                 [csv_path], "--angle: found --angle with length measurements, expected --angle "
                 "only with touches of planes")
    refusals.cli(["calibrate", tracker, "--sigma-deg", "0.01"], [tracker],
                 "--sigma-deg: found --sigma-deg with position measurements, expected "
                 "--sigma-deg only with 6-D poses")
    refusals.cli(["calibrate", csv_path, "--port", "600,-400,100", "--loss-scale", "0.03"],
                 [csv_path], "--loss-scale: found --loss-scale with the linear loss")
    scenario = Path(__file__).resolve().parents[1] / "scenarios" / "geometric_irb120.toml"
    refusals.cli(["check", scenario, "--out", tmp_path / "check", "--tolerance", "10%"],
                 [scenario], "--tolerance: found --tolerance without --baseline")
    assert not (tmp_path / "check").exists()


def test_a_captures_distance_is_blamed_on_the_capture(irb120: RobotModel, tmp_path: Path,
                                                     refusals: Refusals) -> None:
    """A [rig] distance to a point the measurements do not name names the capture file, not
    --distance."""
    q = random_poses(irb120, 60, np.random.default_rng(6))
    rig = Rig(point_names=("a", "b"), points_m=np.array([[0.4, 0.0, 0.3], [0.45, 0.0, 0.3]]))
    data = make_model(irb120, rig, "point").measure(np.zeros(30), q, point=np.arange(60) % 2)
    write_measurements(tmp_path / "m.csv", data)
    (tmp_path / "robot.toml").write_text(robot_to_toml(irb120))
    capture = tmp_path / "capture.toml"
    write_capture(capture, robot="robot.toml", measurements="m.csv",
                  rig=Rig(distances=(Distance("a", "c", 0.05),)))
    refusals.cli(["calibrate", capture], [tmp_path], f"{capture}: found a distance to the "
                 "point 'c'")
