"""Mistakes of the kind a user makes first: a file of another arm, values in the wrong unit."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import Refusals

from twin.cli import main
from twin.dataset import Measurements
from twin.io.measurements import write_measurements
from twin.kinds import KINDS
from twin.kinds.pose import pose_measurements
from twin.kinds.position import position_measurements
from twin.rig import Rig
from twin.robot import RobotModel, random_poses

MODELS = Path(__file__).resolve().parents[1] / "models"


def test_more_joint_columns_than_the_robot_has(csv_path: Path, refusals: Refusals) -> None:
    """A 6-joint file with a 4-joint robot file: one line naming the column, exit 2."""
    refusals.cli(["calibrate", csv_path, "--robot", MODELS / "scara4" / "scara4.toml", "--port",
                  "600,-400,100"], [csv_path], "found the column q5 for a robot of 4 joints")


@pytest.mark.slow
def test_a_port_in_metres_gets_a_hint(csv_path: Path, capsys: pytest.CaptureFixture[str]
                                      ) -> None:
    """--port 0.6,-0.4,0.1 (metres, as the API takes) beside lengths of hundreds of mm: a
    one-line hint naming the flag and the unit it probably is in (and the MISFIT)."""
    assert main(["calibrate", str(csv_path), "--port", "0.6,-0.4,0.1"]) == 0
    captured = capsys.readouterr()
    hint = [line for line in captured.err.splitlines() if "--port" in line]
    assert len(hint) == 1 and "looks like metres" in hint[0]
    assert "MISFIT" in captured.out


@pytest.mark.slow
def test_lengths_in_metres_get_a_hint(measurements: Measurements, tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    """Cable lengths written in metres (0.6 for 600 mm) in a file twin reads in mm: a one-line
    hint naming the file, the median it read and how to convert it (and the MISFIT); a file in
    mm has none, nor one of an encoder zeroed near its shortest pose."""
    path = tmp_path / "metres.csv"
    metres = replace(measurements, values={"length_m": measurements.value("length_m") / 1e3})
    write_measurements(path, metres)
    assert main(["calibrate", str(path), "--port", "600,-400,100"]) == 0
    captured = capsys.readouterr()
    hint = [line for line in captured.err.splitlines() if "look like metres" in line]
    assert len(hint) == 1 and hint[0].startswith(f"twin: warning: {path}: ")
    assert "--length-unit m" in hint[0] and "MISFIT" in captured.out
    # In mm, and in mm from a zero set 1 mm short of the shortest pose (the offset
    # estimated): no hint.
    lengths = measurements.value("length_m")
    for name, values in (("mm.csv", lengths), ("zeroed.csv", lengths - lengths.min() + 1e-3)):
        write_measurements(tmp_path / name, replace(measurements, values={"length_m": values}))
        assert main(["calibrate", str(tmp_path / name), "--port", "600,-400,100",
                     "--estimate-offset"]) == 0
        assert "look like metres" not in capsys.readouterr().err


@pytest.mark.slow
def test_tracker_coordinates_in_metres_get_a_hint(irb120: RobotModel, tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """Tracker positions written in metres: a one-line hint naming the file and how to convert
    it; in mm none. A 6-D pose file is read by the same test of its x, y, z."""
    q = random_poses(irb120, 40, np.random.default_rng(0))
    flange = irb120.flange_transforms(q)
    for scale, hinted in ((1e-3, True), (1.0, False)):
        path = tmp_path / f"tracker-{scale:g}.csv"
        write_measurements(path, position_measurements(q, flange[:, :3, 3] * scale))
        assert main(["calibrate", str(path)]) == 0
        err = capsys.readouterr().err
        assert ("look like metres" in err) == hinted, err
        assert not hinted or (f"twin: warning: {path}: the tracker coordinates" in err
                              and "`twin import --length-unit m`" in err)
        poses = pose_measurements(q, flange[:, :3, 3] * scale, flange[:, :3, :3])
        assert (KINDS.lookup("pose").unit_hint(Rig(), poses) is not None) == hinted
