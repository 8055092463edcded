"""Hostile inputs, class 5 — files others must read: modes and numbers.

Files are created with the process umask (0644 under 022), so that colleagues and services can
read results; numbers in robot files and plans are rounded to what they mean (1 µm, 1e-6°) and
in results to 1e-6 mm and degree (f to 6 significant digits), and every such file reads back to
exactly the numbers it shows: writing what was read gives the same bytes. Measurements stay at
full precision: they are data (tests/test_measurements_io.py holds them to 1e-15 rad).
"""

from __future__ import annotations

import json
import os
import re
import stat
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from conftest import PORT_M

from twin.calibration.pipeline import calibrate
from twin.cli import main
from twin.dataset import Measurements
from twin.io.atomic import write_atomic
from twin.io.measurements import load_plan
from twin.io.results import result_to_dict
from twin.io.robot_file import load_robot, robot_to_toml
from twin.robot import RobotModel

PORT = "600,-400,100"


@pytest.fixture()
def umask(request: pytest.FixtureRequest) -> Iterator[int]:
    """Run with the umask the test is parametrized with, then restore the old one."""
    old = os.umask(request.param)
    yield request.param
    os.umask(old)


@pytest.mark.parametrize("umask", [0o022, 0o027, 0o077], indirect=True)
def test_files_take_the_umask_mode(umask: int, csv_path: Path, tmp_path: Path) -> None:
    """A new file and a replaced one get 0666 & ~umask (0644 under 022), not mkstemp's 0600."""
    path = tmp_path / "new.txt"
    write_atomic(path, "one\n")
    assert stat.S_IMODE(os.stat(path).st_mode) == 0o666 & ~umask
    path.chmod(0o600)
    write_atomic(path, "two\n")
    assert stat.S_IMODE(os.stat(path).st_mode) == 0o666 & ~umask
    out = tmp_path / "result.json"
    assert main(["calibrate", str(csv_path), "--port", PORT, "--json", str(out)]) == 0
    assert stat.S_IMODE(os.stat(out).st_mode) == 0o666 & ~umask


DECIMALS = re.compile(r"-?\d+\.(\d+)")


def _most_decimals(text: str) -> int:
    return max(len(digits) for digits in DECIMALS.findall(text))


def test_robot_files_say_micrometres_and_read_back_exactly(
    irb120: RobotModel, measurements: Measurements, tmp_path: Path
) -> None:
    """An exported model carries no float noise (`-119.99999999999999`): lengths to 1 µm,
    angles to 1e-6°; loaded and written again it is the same bytes."""
    result = tmp_path / "result.json"
    result.write_text(json.dumps(result_to_dict(calibrate(irb120, measurements, PORT_M))))
    out = tmp_path / "identified.toml"
    assert main(["export", str(result), "--format", "dh", "--out", str(out)]) == 0
    text = out.read_text()
    for key, decimals in (("a", 3), ("d", 3), ("alpha", 6), ("theta", 6), ("radius", 3)):
        values = re.findall(rf"\b{key} = (-?[\d.]+)", text)
        assert len(values) == 6 and max(len(v.split(".")[1]) for v in values) <= decimals
    assert robot_to_toml(load_robot(out)) == text


def test_plans_are_typeable_and_read_back_exactly(tmp_path: Path) -> None:
    """A plan's angles have at most 6 decimals (1e-6°), and read back to those numbers."""
    out = tmp_path / "plan.csv"
    assert main(["plan", "--port", PORT, "--poses", "25", "--candidates", "200",
                 "--joint-limits-only", "--out", str(out)]) == 0
    text = out.read_text()
    assert _most_decimals(text) <= 6
    q_rad, _ = load_plan(out)
    rewritten = "\n".join(",".join(repr(round(float(v), 6)) for v in row)
                          for row in np.rad2deg(q_rad))
    assert rewritten == "\n".join(text.splitlines()[1:])


def test_results_are_rounded_to_what_they_mean(irb120: RobotModel, csv_path: Path,
                                                tmp_path: Path) -> None:
    """Result JSON: lengths, metrics and angles to 1e-6, f to 6 significant digits; the robot
    it was identified for is recorded; parsed and dumped again it is the same bytes."""
    out = tmp_path / "result.json"
    assert main(["calibrate", str(csv_path), "--port", PORT, "--json", str(out)]) == 0
    text = out.read_text()
    document = json.loads(text)
    assert json.dumps(document, indent=2) + "\n" == text
    assert document["robot"]["name"] == irb120.name
    assert document["robot"]["dh"]["d"][0] == 290.0
    for block in (document["delta"], document["metrics"], document["sigma"]):
        assert _most_decimals(json.dumps(block)) <= 6
    assert all(float(f"{record['f']:.6g}") == record["f"] for record in document["history"])
