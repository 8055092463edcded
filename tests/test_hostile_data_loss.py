"""Hostile inputs, class 1 — data loss: no command ever writes over one of its inputs.

An output that is one of the command's inputs (by device and inode: the same name, a hard link,
a symbolic link, or a file another input names), an existing device or FIFO, or a folder that
holds something else than what the command writes there, is refused with one line and exit
code 2 before anything is written; every input stays byte for byte as it was.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest
from conftest import PORT_M, Refusals

from twin.calibration.pipeline import calibrate
from twin.dataset import Measurements
from twin.io.capture_file import write_capture
from twin.io.results import result_to_dict, write_json
from twin.io.robot_file import robot_to_toml
from twin.robot import RobotModel
from twin.scenario import parse_scenario
from twin.sim import simulate, write_simulation

PORT = "600,-400,100"
PROGRAM = "q1,q2,q3,q4,q5,q6\n10,20,-30,40,50,60\n-90,45,30,-100,-60,200\n"


@pytest.fixture(scope="module")
def result_document(irb120: RobotModel, measurements: Measurements) -> dict:
    """The JSON document of an LM calibration of the core-made data."""
    return result_to_dict(calibrate(irb120, measurements, PORT_M, method="lm", seed=0))


@pytest.fixture()
def files(tmp_path: Path, csv_path: Path, result_document: dict, irb120: RobotModel
          ) -> dict[str, Path]:
    """A measurement CSV, a result, a program, a robot model: the inputs of the cases."""
    write_json(tmp_path / "result.json", result_document)
    (tmp_path / "program.csv").write_text(PROGRAM)
    (tmp_path / "robot.toml").write_text(robot_to_toml(irb120))
    return {"csv": csv_path, "result": tmp_path / "result.json",
            "program": tmp_path / "program.csv", "robot": tmp_path / "robot.toml"}


@pytest.mark.parametrize(
    ("argv", "output"),
    [
        (["calibrate", "{csv}", "--port", PORT, "--json", "{out}"], "csv"),
        (["compensate", "--identified", "{result}", "--joints", "{program}", "--out", "{out}"],
         "program"),
        (["compensate", "--identified", "{result}", "--joints", "{program}", "--out", "{out}"],
         "result"),
        (["export", "{result}", "--format", "dh", "--out", "{out}"], "result"),
        (["export", "{result}", "--robot", "{robot}", "--format", "dh", "--out", "{out}"],
         "robot"),
        (["identify", "{csv}", "--port", PORT, "--map", "{out}"], "csv"),
        (["plan", "--robot", "{robot}", "--port", PORT, "--poses", "30", "--out", "{out}"],
         "robot"),
        (["predict", "--identified", "{result}", "--joints", "{program}", "--out", "{out}"],
         "program"),
        (["predict", "--identified", "{result}", "--joints", "{program}", "--out", "{out}"],
         "result"),
    ],
)
@pytest.mark.parametrize("alias", ["same name", "hard link", "symbolic link"])
def test_an_output_is_never_an_input(
    argv: list[str], output: str, alias: str, files: dict[str, Path], tmp_path: Path,
    refusals: Refusals,
) -> None:
    """`twin calibrate m.csv --json m.csv`, `twin compensate --joints p.csv --out p.csv`…: the
    output names an input, directly or through a link, and is refused before any work."""
    target = files[output]
    if alias == "hard link":
        os.link(target, tmp_path / "alias")
        target = tmp_path / "alias"
    elif alias == "symbolic link":
        (tmp_path / "alias").symlink_to(target)
        target = tmp_path / "alias"
    paths = {name: str(path) for name, path in files.items()} | {"out": str(target)}
    refusals.cli([arg.format(**paths) for arg in argv], list(files.values()),
                 "found one of this command's inputs")


def test_a_file_named_inside_an_input_is_an_input_too(
    csv_path: Path, tmp_path: Path, irb120: RobotModel, refusals: Refusals
) -> None:
    """`twin calibrate capture.toml --json measurements.csv`: the measurements are named by the
    capture file, not on the command line; the atomic writer still refuses to replace them."""
    (tmp_path / "robot.toml").write_text(robot_to_toml(irb120))
    write_capture(tmp_path / "capture.toml", robot="robot.toml", port_m=PORT_M,
                  measurements=csv_path.name)
    refusals.cli(["calibrate", tmp_path / "capture.toml", "--json", csv_path],
                 [tmp_path], f"{csv_path}: found one of this command's inputs")


def test_a_device_is_never_replaced(csv_path: Path, refusals: Refusals) -> None:
    """`--json /dev/full`: the node is left alone, not replaced by a regular file (root may
    rename over it). Should it ever be replaced, it is restored."""
    full = Path("/dev/full")
    if not full.exists():
        pytest.skip("no /dev/full")
    try:
        refusals.cli(["calibrate", csv_path, "--port", PORT, "--json", full],
                     [csv_path, full], "/dev/full: found a character device")
    finally:
        if os.geteuid() == 0 and not stat.S_ISCHR(os.stat(full).st_mode):
            full.unlink()
            os.mknod(full, 0o666 | stat.S_IFCHR, os.makedev(1, 7))
            os.chmod(full, 0o666)
    assert stat.S_ISCHR(os.stat(full).st_mode)


def test_a_fifo_is_never_replaced(csv_path: Path, tmp_path: Path, refusals: Refusals) -> None:
    """An existing FIFO as --json is refused; it stays a FIFO."""
    fifo = tmp_path / "result.json"
    os.mkfifo(fifo)
    refusals.cli(["calibrate", csv_path, "--port", PORT, "--json", fifo], [csv_path, fifo],
                 "found a FIFO")
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)


SMALL = {
    "name": "small", "seed": 2,
    "port": {"position_mm": [600.0, -400.0, 100.0]},
    "perturbation": {"a_mm": 1.0, "d_mm": 1.0, "alpha_deg": 0.1, "theta_deg": 0.1},
    "poses": {"count": 30},
}


def test_a_capture_into_a_simulation_folder_writes_nothing(
    tmp_path: Path, refusals: Refusals
) -> None:
    """`twin capture --out` a `twin simulate` folder: its measurement file is not a capture's,
    so the capture is refused before it writes a byte (no plan, lock or capture file either)."""
    folder = tmp_path / "sim"
    write_simulation(folder, simulate(parse_scenario(SMALL, tmp_path / "small.toml")))
    plan = tmp_path / "plan.csv"
    plan.write_text(PROGRAM)
    refusals.cli(["capture", "--plan", plan, "--encoder", "serial:///dev/nonexistent",
                  "--robot-source", "manual", "--port", PORT, "--out", folder],
                 [folder, plan], "measurements.csv: line 1: found a measurement file of "
                 "another kind")
    assert sorted(p.name for p in folder.iterdir()) == [
        "capture.toml", "measurements.csv", "robot.toml", "truth.json"]
