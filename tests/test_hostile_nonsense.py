"""Hostile inputs, class 4 — silent nonsense: what cannot be right is refused or warned about.

A result applied to a robot it was not identified for, or with D-H errors no method returns; a
bad flag drowned in four lines of usage; a study folder made for a scheduler that is not
there; a scenario whose poses cannot be found; and data that identify almost nothing,
"calibrated" without a word.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import PORT_M, Refusals

from twin.calibration.pipeline import calibrate
from twin.cli import main
from twin.dataset import Measurements
from twin.io.measurements import write_measurements
from twin.io.results import result_to_dict
from twin.io.robot_file import robot_to_toml
from twin.robot import RobotModel

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "geometric_irb120.toml"
PORT = "600,-400,100"
PROGRAM = "q1,q2,q3,q4,q5,q6\n10,20,-30,40,50,60\n"


@pytest.fixture(scope="module")
def result_document(irb120: RobotModel, measurements: Measurements) -> dict:
    """The JSON document of an LM calibration of the IRB 120's core-made data."""
    return result_to_dict(calibrate(irb120, measurements, PORT_M, method="lm", seed=0))


def _apply(refusals: Refusals, tmp_path: Path, document: dict, match: str,
           robot: Path | None = None) -> None:
    """Both commands that apply a result refuse it with the same line, writing nothing."""
    result, program = tmp_path / "result.json", tmp_path / "program.csv"
    result.write_text(json.dumps(document))
    program.write_text(PROGRAM)
    inputs = [result, program] + ([robot] if robot else [])
    flags = ["--robot", robot] if robot else []
    for argv in (["export", result, "--format", "dh", "--out", tmp_path / "out"],
                 ["compensate", "--identified", result, "--joints", program, "--out",
                  tmp_path / "out"]):
        refusals.cli([*argv, *flags], inputs, match)
        assert not (tmp_path / "out").exists()


def test_a_kilometre_of_dh_error(result_document: dict, tmp_path: Path,
                                 refusals: Refusals) -> None:
    """A result with δa1 = 1 km is beyond the ±5 mm every method searches: not a calibration."""
    document = json.loads(json.dumps(result_document))
    document["delta"]["a"][0] = 1e6
    _apply(refusals, tmp_path, document, "delta.a: found δa1 = 1e+06 mm, expected D-H errors "
           "within the search bounds (±5 mm for δa1)")


def test_delta_and_unknowns_that_disagree(result_document: dict, tmp_path: Path,
                                          refusals: Refusals) -> None:
    """A result whose model unknowns were edited apart from its delta block (0.5 mm on a1) is
    not what a calibration wrote: compensate and predict, which rebuild the model, refuse it."""
    document = json.loads(json.dumps(result_document))
    document["unknowns"]["parameters"][0]["value"] += 0.5
    result, program = tmp_path / "result.json", tmp_path / "program.csv"
    result.write_text(json.dumps(document))
    program.write_text(PROGRAM)
    for command in ("compensate", "predict"):
        refusals.cli([command, "--identified", result, "--joints", program, "--out",
                      tmp_path / "out"], [result, program],
                     "delta.a: found delta.a1 and the unknowns disagree, expected a result as "
                     "twin calibrate wrote it")
        assert not (tmp_path / "out").exists()


def test_another_robots_result(result_document: dict, tmp_path: Path, irb120: RobotModel,
                               refusals: Refusals) -> None:
    """The IRB 120's result applied to another robot: refused by name, and by nominal table
    when the name is the same but the table is not."""
    other = tmp_path / "other.toml"
    other.write_text(robot_to_toml(irb120).replace("ABB IRB 120", "ABB IRB 140"))
    _apply(refusals, tmp_path, result_document, "robot.name: found a result identified for "
           "'ABB IRB 120', expected a result for 'ABB IRB 140'", robot=other)
    moved = tmp_path / "moved.toml"
    moved.write_text(robot_to_toml(irb120.perturbed(np.r_[0.0, 0.01, np.zeros(22)])))
    _apply(refusals, tmp_path, result_document, "robot.dh.a: found a result identified for "
           "another nominal table of ABB IRB 120 (a2 differs)", robot=moved)


def test_the_same_robot_within_the_stated_tolerance(
    result_document: dict, tmp_path: Path, irb120: RobotModel, capsys: pytest.CaptureFixture[str]
) -> None:
    """A nominal table 0.4 µm and 2e-6° away (say, the robot written in metres and radians
    elsewhere, rounded to a model file here) is the same robot: applied without a word about
    the robot (the one warning is the result's own: what its data did not see)."""
    robot = tmp_path / "robot.toml"
    robot.write_text(robot_to_toml(irb120.perturbed(np.repeat([4e-7, 4e-7, 4e-8, 4e-8], 6))))
    result = tmp_path / "result.json"
    result.write_text(json.dumps(result_document))
    assert main(["export", str(result), "--robot", str(robot), "--format", "dh", "--out",
                 str(tmp_path / "out.toml")]) == 0
    err = capsys.readouterr().err
    assert err.count("twin: warning:") == 1 and "held at the nominal" in err, err


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        (["calibrate", "m.csv", "--seed", "abc"], "--seed: found 'abc', expected an integer"),
        (["study", str(SCENARIO), "--out", "x", "--trials", "0"], "--trials: found '0', "
         "expected an integer in 1..100000"),
        (["study", str(SCENARIO), "--out", "x", "--workers", "x"], "--workers: found 'x', "
         "expected an integer in 1..1024"),
        (["calibrate", "m.csv", "--train-fraction", "1.5"], "--train-fraction: found '1.5', "
         "expected a share in (0, 1]"),
        (["plan", "--port", PORT], "twin plan: found no --poses, --out, expected every "
         "argument `twin plan --help` marks as required"),
        (["calibrate", "m.csv", "--no-such-flag"], "twin calibrate: found unrecognized "
         "arguments --no-such-flag, expected only those `twin calibrate --help` lists"),
        # A mistyped flag is named, not taken for the required one it was meant to be.
        (["export", "r.json", "--frmat", "urdf", "--out", "x"], "twin export: found "
         "unrecognized arguments --frmat, expected only those `twin export --help` lists "
         "(did you mean --format?)"),
        (["export", "r.json", "--format=urdf", "--out", "x", "--robt", "r.toml"],
         "found unrecognized arguments --robt, expected only those `twin export --help` lists "
         "(did you mean --robot?)"),
        (["predict", "r.json", "--identified", "r.json", "--joints", "j.csv", "--out", "x"],
         "twin predict: found unrecognized arguments r.json, expected only those "
         "`twin predict --help` lists"),
        (["--frob", "calibrate", "m.csv"], "twin: found unrecognized arguments --frob, "
         "expected only those `twin COMMAND --help` lists"),
    ],
)
def test_a_bad_flag_is_one_line(argv: list[str], match: str, tmp_path: Path,
                                refusals: Refusals) -> None:
    """argparse's own errors come out as one `twin: error:` line, not four lines of usage."""
    refusals.cli(argv, [SCENARIO], match)
    assert not (tmp_path / "x").exists()


def test_what_argparse_takes_is_not_refused_as_unknown() -> None:
    """A command names the flags it does not know before it parses, so what argparse takes as
    a value or an abbreviation must not look unknown: ``-`` (stdin), a negative list,
    ``--flag=VALUE``, the unique start of a flag, and a word after ``--``."""
    from twin.cli import build_parser

    args = build_parser().parse_args(["calibrate", "-", "--port", "-500,-300,150", "--seed=3",
                                      "--meth", "lm"])
    assert (str(args.input), args.port, args.seed, args.method) == \
        ("-", ["-500,-300,150"], 3, "lm")
    assert str(build_parser().parse_args(["calibrate", "--", "-m.csv"]).input) == "-m.csv"


@pytest.mark.parametrize(
    ("scheduler", "match"),
    [
        ("not a url", "--scheduler: found 'not a url', expected the address of a running dask "
         "scheduler"),
        ("http://127.0.0.1:8786", "found 'http://127.0.0.1:8786'"),
        ("tcp://127.0.0.1:1", "found no scheduler reachable at tcp://127.0.0.1:1"),
    ],
)
def test_a_study_for_a_scheduler_that_is_not_there(
    scheduler: str, match: str, tmp_path: Path, refusals: Refusals
) -> None:
    """--scheduler unreachable or not a URL: refused before the study folder is created."""
    refusals.cli(["study", SCENARIO, "--out", tmp_path / "study", "--scheduler", scheduler],
                 [SCENARIO], match)
    assert not (tmp_path / "study").exists()


def test_poses_that_cannot_be_found(tmp_path: Path, refusals: Refusals) -> None:
    """A scenario whose cable range no pose reaches is the user's setting: exit 2, naming it."""
    scenario = tmp_path / "scenario.toml"
    text = SCENARIO.read_text().replace('robot = "../models/irb120.toml"\n', "")
    scenario.write_text(text.replace("range_mm = [100.0, 1500.0]", "range_mm = [100.0, 101.0]")
                        .replace("count = 120", "count = 5"))
    refusals.cli(["simulate", scenario, "--out", tmp_path / "out"], [scenario],
                 "[port], [poses], [encoder] range_mm: found only 0 of 5 poses that satisfy "
                 "the constraints")
    assert not (tmp_path / "out").exists()


def _calibrate_process(path: Path) -> subprocess.CompletedProcess[str]:
    """`twin calibrate` with stderr and stdout in one stream, in the order they were written."""
    return subprocess.run([sys.executable, "-m", "twin", "calibrate", str(path), "--port", PORT],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          timeout=120, check=False,
                          env={**os.environ, "PYTHONUNBUFFERED": "1"})


@pytest.mark.slow
def test_rank_deficient_data_are_warned_about_before_the_calibration(
    measurements: Measurements, tmp_path: Path
) -> None:
    """Every row the same pose: rank 1 of the 19 directions well-spread poses reach. One
    warning line, before the calibration is printed; the usual data (rank 19) get none."""
    same = tmp_path / "same.csv"
    write_measurements(same, measurements.subset(np.zeros(40, dtype=int)))
    run = _calibrate_process(same)
    assert run.returncode == 0, run.stdout
    lines = run.stdout.splitlines()
    warnings = [i for i, line in enumerate(lines) if line.startswith("twin: warning:")]
    assert len(warnings) == 1 and warnings[0] == 0, run.stdout
    assert "training poses identify 1 of the 19 directions well-spread poses identify" \
        in lines[0]
    assert "Traceback" not in run.stdout
    spread = tmp_path / "spread.csv"
    write_measurements(spread, measurements)
    run = _calibrate_process(spread)
    assert run.returncode == 0 and "twin: warning" not in run.stdout, run.stdout


def test_table_columns_never_run_together() -> None:
    """A value as wide as its column or wider keeps a space before it (a 500 m link once read
    ``499059.9413499059.7919``)."""
    from twin.report.display import slot

    row = slot(499.0599413, True, width=10) + slot(499.0597919, True, width=10)
    assert row.split() == ["499059.9413", "499059.7919"]
    assert slot(0.0012953, True, width=10) == "    1.2953"
