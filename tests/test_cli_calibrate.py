"""`twin calibrate` end to end, and every user mistake as one line with exit code 2."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from twin.cli import main
from twin.dataset import Measurements
from twin.io.measurements import write_measurements

ROOT = Path(__file__).resolve().parents[1]
PORT = "600,-400,100"


def test_summary_and_json(csv_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                          true_delta: np.ndarray) -> None:
    """The summary names the metrics; the JSON has #2's keys in mm and degrees."""
    out = tmp_path / "out" / "result.json"
    assert main(["calibrate", str(csv_path), "--port", PORT, "--json", str(out)]) == 0
    printed = capsys.readouterr().out
    for text in ("before (valid.)", "after, validation", "Identified D-H errors", "STD"):
        assert text in printed
    document = json.loads(out.read_text())
    assert document["method"] == "lm" and document["seed"] == 0
    assert set(document["delta"]) == {"a", "d", "alpha", "theta"}
    assert set(document["metrics"]) == {"before", "train", "validation"}
    assert set(document["metrics"]["before"]) == {"rmse", "mae", "std", "max"}
    assert document["history"][0]["iteration"] == 0 and document["iterations"] >= 1
    # Identifiable and large: δa1 (mm) comes back near the truth.
    assert document["delta"]["a"][0] == pytest.approx(true_delta[0, 0] * 1e3, abs=0.02)
    assert document["metrics"]["validation"]["rmse"] < 0.02 < document["metrics"]["before"]["rmse"]


def test_method_alias_and_seed(csv_path: Path, tmp_path: Path) -> None:
    """`--method m2` is LM; the seed is recorded."""
    out = tmp_path / "r.json"
    assert main(["calibrate", str(csv_path), "--port", PORT, "--method", "M2", "--seed", "4",
                 "--json", str(out)]) == 0
    document = json.loads(out.read_text())
    assert document["method"] == "lm" and document["seed"] == 4


def _write(tmp_path: Path, name: str, content: str | bytes) -> Path:
    path = tmp_path / name
    path.write_bytes(content.encode() if isinstance(content, str) else content)
    return path


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["calibrate", "{tmp}/missing.csv", "--port", PORT], "missing.csv: found no such file"),
        (["calibrate", "{csv}"], "found no --port"),
        (["calibrate", "{csv}", "--port", "1,2"], "--port: found '1,2', expected three finite"),
        (["calibrate", "{csv}", "--port", "a,b,c"], "expected three finite numbers"),
        (["calibrate", "{csv}", "--port", PORT, "--method", "newton"],
         "found unknown method 'newton', expected one of ekf (m1), lm (m2)"),
        (["calibrate", "{csv}", "--port", PORT, "--robot", "{tmp}/bad_robot.toml"],
         "bad_robot.toml: length_unit: found nothing, expected one of mm, m"),
        (["calibrate", "{short}", "--port", PORT],
         "short.csv: found 20 poses, expected at least 30"),
        (["calibrate", "{limits}", "--port", PORT], "column q2: found 130 deg"),
    ],
)
def test_user_mistakes_exit_2_with_one_line(
    argv: list[str], message: str, csv_path: Path, tmp_path: Path, measurements: Measurements,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Exit code 2, one line on stderr naming the file or flag, and no JSON written."""
    _write(tmp_path, "bad_robot.toml", 'name = "x"\nconvention = "dh"\nangle_unit = "deg"\n'
           "joints = []\n")
    write_measurements(tmp_path / "short.csv", measurements.subset(np.arange(20)))
    _write(tmp_path, "limits.csv", "q1,q2,q3,q4,q5,q6,length\n" + "0,130,0,0,0,0,700\n" * 40)
    paths = {"tmp": str(tmp_path), "csv": str(csv_path), "short": str(tmp_path / "short.csv"),
             "limits": str(tmp_path / "limits.csv")}
    out = tmp_path / "never.json"
    code = main([arg.format(**paths) for arg in argv] + ["--json", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("twin: error: ") and message in err, err
    assert not out.exists()


@pytest.mark.slow
def test_console_entry_point_has_no_traceback(tmp_path: Path) -> None:
    """`python -m twin` on binary garbage: exit 2, one line, no traceback."""
    garbage = _write(tmp_path, "garbage.csv", bytes(range(256)))
    run = subprocess.run([sys.executable, "-m", "twin", "calibrate", str(garbage), "--port", PORT],
                         capture_output=True, text=True, check=False)
    assert run.returncode == 2
    assert "Traceback" not in run.stderr and "found binary data" in run.stderr
    assert run.stdout == ""


def test_example_dataset_calibrates(capsys: pytest.CaptureFixture[str]) -> None:
    """The dataset shipped for the README calibrates below 0.02 mm validation RMSE."""
    path = ROOT / "examples" / "irb120_lm" / "measurements.csv"
    assert main(["calibrate", str(path), "--port", PORT]) == 0
    lines = capsys.readouterr().out.splitlines()
    validation = next(line for line in lines if "after, validation" in line)
    assert float(validation.split()[2]) < 0.02


def test_capture_calibration_table_sets_unknowns_and_split(
    csv_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A capture's [calibration] table chooses the unknowns and the split; flags win."""
    from twin.calibration.settings import CalibrationSettings
    from twin.io.capture_file import write_capture
    from twin.io.robot_file import default_robot, robot_to_toml

    (tmp_path / "robot.toml").write_text(robot_to_toml(default_robot()))
    capture = tmp_path / "capture.toml"
    write_capture(capture, robot="robot.toml", port_m=np.array([0.6, -0.4, 0.1]),
                  measurements=csv_path.name,
                  calibration=CalibrationSettings(estimate=("offset",), train_fraction=0.75))
    out = tmp_path / "r.json"
    assert main(["calibrate", str(capture), "--json", str(out)]) == 0
    document = json.loads(out.read_text())
    assert "offset" in document and abs(document["offset"]) < 0.05
    assert "90 train / 30 validation" in capsys.readouterr().out
    assert main(["calibrate", str(capture), "--train-fraction", "0.5", "--json", str(out)]) == 0
    assert "60 train / 60 validation" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ("[calibration]\ntrain_fraction = 1.5\n", "[calibration] train_fraction: found 1.5"),
        ("[calibration]\nestimate_port = 1\n", "expected true or false"),
        ("[calibration]\nsplit = 0.8\n", "found unknown key 'split'"),
        ("[calibration]\nstop = \"fast\"\n", "[calibration] stop: found 'fast', expected one of "
         "converge, paper"),
        ("[calibration]\nmax_iterations = 0\n", "[calibration] max_iterations: found 0"),
    ],
)
def test_bad_capture_calibration_table(
    csv_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], table: str, message: str
) -> None:
    """A wrong [calibration] entry is one line naming the key, exit code 2."""
    from twin.io.robot_file import default_robot, robot_to_toml

    (tmp_path / "robot.toml").write_text(robot_to_toml(default_robot()))
    capture = tmp_path / "capture.toml"
    capture.write_text('robot = "robot.toml"\nport_mm = [600, -400, 100]\n'
                       f'measurements = "{csv_path.name}"\n' + table)
    assert main(["calibrate", str(capture)]) == 2
    assert message in capsys.readouterr().err


@pytest.mark.slow
def test_stop_protocol_from_capture_and_flag(
    csv_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The capture's stop protocol is used and reported; --stop and --max-iterations win; the
    JSON says which test stopped each stage."""
    from twin.calibration.settings import CalibrationSettings
    from twin.io.capture_file import write_capture
    from twin.io.robot_file import default_robot, robot_to_toml

    (tmp_path / "robot.toml").write_text(robot_to_toml(default_robot()))
    capture = tmp_path / "capture.toml"
    write_capture(capture, robot="robot.toml", port_m=np.array([0.6, -0.4, 0.1]),
                  measurements=csv_path.name, calibration=CalibrationSettings(stop="paper"))
    out = tmp_path / "r.json"
    assert main(["calibrate", str(capture), "--json", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "(paper protocol)" in printed and "the paper's rule fired" in printed
    document = json.loads(out.read_text())
    assert document["stop"]["protocol"] == "paper" and document["stop_reason"] == "f_change"
    assert document["converged"] is False
    assert main(["calibrate", str(capture), "--stop", "converge", "--method", "m9",
                 "--json", str(out)]) == 0
    printed = capsys.readouterr().out
    document = json.loads(out.read_text())
    assert [stage["method"] for stage in document["stop"]["stages"]] == ["amlm", "bipso"]
    assert document["stop"]["stages"][0]["stop_reason"] in ("ftol", "xtol", "gtol")
    assert document["converged"] is True and "stage bipso" in printed
    assert main(["calibrate", str(capture), "--max-iterations", "1", "--json", str(out)]) == 0
    document = json.loads(out.read_text())
    assert document["stop_reason"] == "max_iterations" and document["iterations"] == 1
    assert main(["calibrate", str(capture), "--max-iterations", "0"]) == 2
    assert "--max-iterations: found '0', expected an integer" in capsys.readouterr().err
