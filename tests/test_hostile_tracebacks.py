"""Hostile inputs, class 2 — tracebacks: every mistake in a flag, a path or a file is one line.

Each case is a mistake a careless or unlucky user makes; each must end with exit code 2, one
line ``twin: error: <source>: …: found X, expected Y`` on stderr, no traceback, and its inputs
unchanged.
"""

from __future__ import annotations

import ctypes
import json
import os
import resource
from pathlib import Path

import pytest
from conftest import Refusals

from twin.errors import InputError
from twin.io.paths import MAX_LINE_CHARS, MAX_NESTING, read_toml
from twin.io.robot_file import robot_to_toml
from twin.kinds import KINDS
from twin.robot import RobotModel

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "geometric_irb120.toml"
PORT = "600,-400,100"
RESULT = {"delta": {key: [0.0] * 6 for key in ("a", "d", "alpha", "theta")}}


@pytest.fixture()
def files(tmp_path: Path, csv_path: Path, irb120: RobotModel) -> dict[str, Path]:
    """Valid inputs, each case breaking one thing: a CSV, a result, a program, a robot."""
    (tmp_path / "result.json").write_text(json.dumps(RESULT))
    (tmp_path / "program.csv").write_text("q1,q2,q3,q4,q5,q6\n10,20,-30,40,50,60\n")
    (tmp_path / "robot.toml").write_text(robot_to_toml(irb120))
    (tmp_path / "folder").mkdir()
    return {"csv": csv_path, "result": tmp_path / "result.json",
            "program": tmp_path / "program.csv", "robot": tmp_path / "robot.toml",
            "folder": tmp_path / "folder", "tmp": tmp_path}


def _run(refusals: Refusals, files: dict[str, Path], argv: list[str], match: str) -> None:
    paths = {name: str(path) for name, path in files.items()}
    inputs = [path for name, path in files.items() if name != "tmp"]
    refusals.cli([arg.format(**paths) for arg in argv], inputs, match.format(**paths))


@pytest.mark.parametrize(
    "argv",
    [
        ["calibrate", "{csv}", "--port", PORT],
        ["simulate", str(SCENARIO), "--out", "{tmp}/never"],
        ["identify", "{csv}", "--port", PORT],
        ["plan", "--port", PORT, "--poses", "30", "--out", "{tmp}/never.csv"],
        ["compensate", "--identified", "{result}", "--joints", "{program}", "--out", "{tmp}/c"],
        ["capture", "--plan", "{program}", "--encoder", "serial:///dev/null",
         "--robot-source", "manual", "--port", PORT, "--out", "{tmp}/never"],
        ["virtual-encoder", str(SCENARIO)],
    ],
    ids=lambda argv: argv[0],
)
def test_a_negative_seed(argv: list[str], files: dict[str, Path], refusals: Refusals) -> None:
    """`--seed -1` is refused where it is parsed, by every command that takes a seed."""
    _run(refusals, files, [*argv, "--seed", "-1"], "--seed: found '-1', expected an integer in 0..")


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        (["calibrate", "{csv}", "--port", PORT, "--json", "{folder}"],
         "{folder}: found a directory"),
        (["calibrate", "{csv}", "--port", PORT, "--rerun-save", "{folder}"],
         "{folder}: found a directory"),
        (["identify", "{csv}", "--port", PORT, "--map", "{folder}"], "found a directory"),
        (["export", "{result}", "--format", "dh", "--out", "{folder}"], "found a directory"),
        (["compensate", "--identified", "{result}", "--joints", "{program}", "--out",
          "{folder}"], "found a directory"),
        (["predict", "--identified", "{result}", "--joints", "{program}", "--out",
          "{folder}"], "found a directory"),
        (["calibrate", "{csv}", "--port", PORT, "--json", "{csv}/result.json"],
         "result.json: found a path under the file {csv}"),
        (["simulate", str(SCENARIO), "--out", "{csv}/run"], "found a path under the file"),
        (["simulate", str(SCENARIO), "--out", "{program}"], "{program}: found a file, expected "
         "a folder"),
        (["plan", "--port", PORT, "--poses", "30", "--out", "{folder}"], "found a directory"),
        (["capture", "--plan", "{program}", "--encoder", "serial:///dev/null", "--robot-source",
          "manual", "--port", PORT, "--out", "{program}"], "found a file, expected a folder"),
        (["study", str(SCENARIO), "--out", "{program}"], "found a file, expected a folder"),
    ],
)
def test_an_output_that_cannot_be_written(
    argv: list[str], match: str, files: dict[str, Path], refusals: Refusals
) -> None:
    """--json/--out/--map into an existing directory, under a regular file, or a folder output
    naming a file: refused before any work."""
    _run(refusals, files, argv, match)


CAP_DAC_OVERRIDE = 1
"""The capability that lets root write where the permission bits say no (linux/capability.h)."""
PR_CAPBSET_DROP = 24


def _without_dac_override() -> None:
    """In the child, before exec: drop CAP_DAC_OVERRIDE from the bounding set, so that the
    command run as root meets permission bits like any user."""
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.prctl(PR_CAPBSET_DROP, CAP_DAC_OVERRIDE, 0, 0, 0) != 0:
        raise OSError(ctypes.get_errno(), "prctl(PR_CAPBSET_DROP)")


@pytest.mark.slow
def test_a_read_only_folder(csv_path: Path, tmp_path: Path, refusals: Refusals) -> None:
    """--json into a folder the user may not write: one line naming the folder. Root writes
    anywhere, so as root the command runs without that capability."""
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    root = {"preexec_fn": _without_dac_override} if os.geteuid() == 0 else {}
    try:
        refusals.process(["calibrate", csv_path, "--port", PORT, "--json", locked / "r.json"],
                         [csv_path, locked], f"found a folder {locked} that is not writable",
                         **root)
    finally:
        locked.chmod(0o755)


@pytest.mark.slow
def test_a_full_disk(csv_path: Path, tmp_path: Path, refusals: Refusals) -> None:
    """A write that fails half-way (a file-size limit stands in for a full disk: the same
    OSError from write()) is one line naming the file and the operation; nothing is left."""
    out = tmp_path / "out"

    def limit_file_size() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (2000, 2000))

    refusals.process(["calibrate", csv_path, "--port", PORT, "--json", out / "result.json"],
                     [csv_path], "result.json: found file too large while writing it",
                     preexec_fn=limit_file_size)
    assert list(out.iterdir()) == []


KINDS_TEXT = ", ".join(kind.columns_text for kind in list(KINDS.values())[:-1]) \
    + f" or {list(KINDS.values())[-1].columns_text}"
"""Every measurement kind's columns, as a measurement CSV's description lists them."""


@pytest.mark.parametrize(
    ("name", "content", "match"),
    [
        ("field.csv", "q1,q2,q3,q4,q5,q6,length,note\n" + "0,0,0,0,0,0,700," + "x" * 2**20
         + "\n", "line 2: found a line of"),
        ("comment.csv", "#" + "x" * 2**20 + "\nq1,q2,q3,q4,q5,q6,length\n",
         f"line 1: found a line of {2**20 + 1} characters, expected a measurement CSV (q1..q6 "
         f"in deg and {KINDS_TEXT}) with lines of at most {MAX_LINE_CHARS}"),
    ],
    ids=["1 MB field", "1 MB comment"],
)
def test_a_huge_csv_line(name: str, content: str, match: str, tmp_path: Path,
                         refusals: Refusals) -> None:
    """A 1 MB field or comment line in a CSV (beyond the csv module's field limit)."""
    path = tmp_path / name
    path.write_text(content)
    refusals.cli(["calibrate", path, "--port", PORT], [path], f"{path}: {match}")


def test_dev_zero_as_a_measurement_file(refusals: Refusals) -> None:
    """/dev/zero never ends: only regular files are read."""
    refusals.cli(["calibrate", "/dev/zero", "--port", PORT], [],
                 "/dev/zero: found a character device, expected a measurement CSV")


ROBOT = (ROOT / "models" / "irb120.toml").read_text()


@pytest.mark.parametrize(
    ("text", "match"),
    [
        (ROBOT.replace('length_unit = "mm"', 'length_unit = ["mm"]'),
         "length_unit: found ['mm'], expected one of mm, m"),
        (ROBOT.replace('angle_unit = "deg"', "angle_unit = { deg = 1 }"),
         "angle_unit: found {'deg': 1}, expected one of deg, rad"),
        (ROBOT.replace("d = 290.0", "d = 1e300", 1),
         "joint 1 d: found 1e+300, expected a number within ±100000 mm"),
        (ROBOT.replace("d = 290.0", "d = 500000.0", 1),
         "joint 1 d: found 500000.0, expected a number within ±100000 mm"),
        ("a = " + "[" * 5000 + "]" * 5000 + "\n",
         f"found arrays or tables nested 5000 deep, expected a robot model TOML file nested at "
         f"most {MAX_NESTING} deep"),
    ],
    ids=["unit as a list", "unit as a table", "link of 1e300 mm", "link of 500 m", "deep TOML"],
)
def test_a_broken_robot_file(text: str, match: str, tmp_path: Path, csv_path: Path,
                             refusals: Refusals) -> None:
    """A unit given as a list or a table, a link length of 1e300 or of 500 m (a unit mistake),
    arrays nested 5000 deep."""
    robot = tmp_path / "robot.toml"
    robot.write_text(text)
    refusals.cli(["calibrate", csv_path, "--port", PORT, "--robot", robot], [robot, csv_path],
                 f"{robot}: {match}")


def test_keys_nested_to_the_limit_are_read_and_one_key_deeper_is_refused(tmp_path: Path
                                                                         ) -> None:
    """A value MAX_NESTING dotted keys deep, beside a long list of numbers, is read; one key
    deeper is refused, naming the limit."""
    path = tmp_path / "deep.toml"
    numbers = "n = [" + ", ".join(["1"] * 10000) + "]\n"
    path.write_text(numbers + ".".join(["x"] * MAX_NESTING) + " = 1\n")
    document = read_toml(path, "a test file")
    assert len(document["n"]) == 10000
    path.write_text(numbers + ".".join(["x"] * (MAX_NESTING + 1)) + " = 1\n")
    with pytest.raises(InputError, match=f"keys nested more than {MAX_NESTING} deep"):
        read_toml(path, "a test file")


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ("[poses]\ncount = 1000000000\n", "[poses] count: found 1000000000, expected an "
         "integer in 1..100000"),
        ("x" + ".x" * 5000 + " = 1\n", f"found keys nested more than {MAX_NESTING} deep"),
    ],
    ids=["1e9 poses", "5000 dotted keys"],
)
@pytest.mark.slow
def test_a_broken_scenario(change: str, match: str, tmp_path: Path, refusals: Refusals) -> None:
    """A scenario asking for 1e9 poses, or keys nested 5000 deep without a bracket."""
    scenario = tmp_path / "scenario.toml"
    text = SCENARIO.read_text().replace('robot = "../models/irb120.toml"\n', "")
    scenario.write_text(text.replace("[poses]\ncount = 120\n", change))
    refusals.cli(["simulate", scenario, "--out", tmp_path / "out"], [scenario], match)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("content", "match"),
    [
        ("[" * 100000 + "]" * 100000, "found arrays or tables nested 100000 deep"),
        ("[1, 2, 3]", "found a JSON list, expected a JSON object"),
        ('{"methods": [1, 2]}', "methods: found a 'methods' that is not an object of results"),
        ('{"methods": {"lm": 5}}', "methods: found a 'methods' that is not an object"),
        ('{"delta": {"a": "0"}}', "delta: found no valid 'delta'"),
        ('{"delta": {"a": [1' + "0" * 400 + ', 0, 0, 0, 0, 0], "d": [0, 0, 0, 0, 0, 0], '
         '"alpha": [0, 0, 0, 0, 0, 0], "theta": [0, 0, 0, 0, 0, 0]}}',
         "delta: found a non-finite value in 'delta'"),
        ('{"robot": [], "delta": {"a": [0, 0, 0, 0, 0, 0], "d": [0, 0, 0, 0, 0, 0], '
         '"alpha": [0, 0, 0, 0, 0, 0], "theta": [0, 0, 0, 0, 0, 0]}}',
         "robot: found a 'robot' without a name"),
    ],
    ids=["deep", "list", "methods list", "method not an object", "delta text", "1e400",
         "robot list"],
)
def test_a_result_of_the_wrong_shape(content: str, match: str, tmp_path: Path,
                                     refusals: Refusals) -> None:
    """Result files of the wrong shape: each names what is wrong and where."""
    result = tmp_path / "result.json"
    result.write_text(content)
    refusals.cli(["export", result, "--format", "dh", "--out", tmp_path / "x.toml"], [result],
                 match)
    assert not (tmp_path / "x.toml").exists()


@pytest.mark.parametrize(
    ("flag", "match"),
    [
        (["--settle-interval", "inf"], "--settle-interval: found 'inf', expected a number in "
         "[0, 86400]"),
        (["--settle-tol", "nan"], "--settle-tol: found 'nan'"),
        (["--max-failures", "1e9"], "--max-failures: found '1e9', expected an integer in "
         "1..1000"),
        (["--joint-log-wait", "-1"], "--joint-log-wait: found '-1', expected a time in [0, "
         "86400] s, or none"),
    ],
)
def test_a_capture_flag_out_of_range(flag: list[str], match: str, files: dict[str, Path],
                                     refusals: Refusals) -> None:
    """Capture's numbers are finite and in range where they are parsed."""
    _run(refusals, files, ["capture", "--plan", "{program}", "--encoder", "serial:///dev/null",
                           "--robot-source", "manual", "--port", PORT, "--out", "{tmp}/cap",
                           *flag], match)
