"""Hostile inputs, class 8 — messages: every refusal says, in the project's one line, which
flag or file is wrong, what was found and what was expected, and quotes no file's content.

A file of another kind given where a CSV was expected (a scenario's ``plan =
"../../etc/passwd"``) used to have its first line printed; argparse's own failures came in its
words (``expected one argument`` for ``--port -500,-300,150``, ``invalid choice``); a method
name without its flag; a known distance told twice; a tolerance of 1e9 %.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import PORT_M, Refusals

from twin.calibration.pipeline import calibrate
from twin.dataset import Measurements
from twin.io.capture_file import write_capture
from twin.io.results import result_to_dict, write_json
from twin.io.robot_file import robot_to_toml
from twin.robot import RobotModel

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "geometric_irb120.toml"
PORT = "600,-400,100"
SECRET = "hunter2"
PRIVATE = f"user:{SECRET}:0:0:root:/root:/bin/bash\ndaemon:x:1:1::/:/sbin/nologin\n"
"""A private file's lines (as /etc/passwd), which no error may quote."""


@pytest.fixture(scope="module")
def result_document(irb120: RobotModel, measurements: Measurements) -> dict:
    """The JSON document of an LM calibration of the core-made data."""
    return result_to_dict(calibrate(irb120, measurements, PORT_M, method="lm", seed=0))


@pytest.fixture()
def private(tmp_path: Path) -> Path:
    path = tmp_path / "private.txt"
    path.write_text(PRIVATE)
    return path


def _quiet(error: str) -> None:
    assert SECRET not in error and "/bin/bash" not in error, error


def test_a_scenarios_plan_naming_a_private_file(private: Path, tmp_path: Path,
                                                refusals: Refusals) -> None:
    """`plan = "../../etc/passwd"` printed `root:x:0:0:…`: now the header is named by the
    columns it lacks."""
    scenario = tmp_path / "s.toml"
    scenario.write_text(SCENARIO.read_text().replace("count = 120", f'plan = "{private}"')
                        .replace('"../models/', f'"{ROOT}/models/'))
    _quiet(refusals.cli(["simulate", scenario, "--out", tmp_path / "out"], [scenario, private],
                        f"{private}: line 1: found a header without q1,q2,q3,q4,q5,q6, "
                        "expected a header q1,q2,q3,q4,q5,q6"))
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    "argv",
    [
        ["calibrate", "{private}", "--port", PORT],
        ["identify", "{private}", "--port", PORT],
        ["predict", "--identified", "{result}", "--joints", "{private}", "--out", "{tmp}/p.csv"],
        ["compensate", "--identified", "{result}", "--joints", "{private}", "--out",
         "{tmp}/c.csv"],
        ["capture", "--plan", "{private}", "--encoder", "serial:///dev/null", "--robot-source",
         "manual", "--port", PORT, "--out", "{tmp}/cap"],
    ],
    ids=lambda argv: argv[0],
)
def test_a_private_file_as_a_csv(argv: list[str], private: Path, tmp_path: Path,
                                 result_document: dict, refusals: Refusals) -> None:
    """Every command that reads a CSV names what the file lacks, never its lines."""
    result = tmp_path / "result.json"
    write_json(result, result_document)
    paths = {"private": private, "result": result, "tmp": tmp_path}
    _quiet(refusals.cli([arg.format(**paths) for arg in argv], [tmp_path],
                        f"{private}: line 1: found a header without q1,q2,q3,q4,q5,q6"))


def test_a_cell_is_quoted_short(tmp_path: Path, refusals: Refusals) -> None:
    """A cell that is not a number is quoted, cut short: not a 60 000-character line."""
    csv = tmp_path / "m.csv"
    csv.write_text("q1,q2,q3,q4,q5,q6,length\n" + "1,2,3,4,5,6," + "x" * 60_000 + "\n")
    error = refusals.cli(["calibrate", csv, "--port", PORT], [csv],
                         f"{csv}: line 2, column length: found 'xxxx")
    assert len(error) < 300


@pytest.mark.slow
def test_a_huge_value_in_a_scenario_is_quoted_short(tmp_path: Path,
                                                    refusals: Refusals) -> None:
    """A list of a hundred thousand numbers where a count belongs: named, not echoed."""
    scenario = tmp_path / "s.toml"
    scenario.write_text(SCENARIO.read_text().replace("count = 120", "count = ["
                                                     + ", ".join(["1"] * 100_000) + "]")
                        .replace('"../models/', f'"{ROOT}/models/'))
    error = refusals.cli(["simulate", scenario, "--out", tmp_path / "out"], [scenario],
                         f"{scenario}: [poses] count: found [1, 1, 1")
    assert len(error) < 400


def test_values_that_start_with_a_minus(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                        ) -> None:
    """`--port -500,-300,150` is a port, not an unknown flag (argparse alone said "expected
    one argument"); so is `-.5,400,1e2`."""
    from twin.cli import main

    out = tmp_path / "plan.csv"
    assert main(["plan", "--port", "-500,-300,150", "--port", "-.5,400,1e2", "--poses", "30",
                 "--joint-limits-only", "--out", str(out)]) == 0
    assert out.exists() and "twin: error" not in capsys.readouterr().err


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        (["calibrate", "{csv}", "--port"], "--port: found no value, expected one (a value "
         "that starts with '-' and is not a number: --flag=VALUE)"),
        (["calibrate", "{csv}", "--port", PORT, "--method", "gauss"], "--method: found "
         "unknown method 'gauss', expected one of ekf (m1), lm (m2), pso (m3)"),
        (["calibrate", "{csv}", "--port", PORT, "--stop", "fast"], "--stop: found 'fast', "
         "expected one of converge, paper"),
        (["calibrate", "{csv}", "--port", PORT, "--estimate"], "twin calibrate: found "
         "--estimate, which could be --estimate-port, --estimate-attachment"),
        (["calibrate", "{csv}", "--port", PORT, "--estimate-offset=yes"], "--estimate-offset: "
         "found the value 'yes', expected the flag alone (it takes no value)"),
        (["study", str(SCENARIO), "--out", "{tmp}/s", "--workers", "2", "--scheduler",
          "tcp://127.0.0.1:1"], "--scheduler: found it with --workers, expected one of the two"),
        (["simulate"], "twin simulate: found no SCENARIO.toml, --out, expected every argument "
         "`twin simulate --help` marks as required"),
        (["frobnicate"], "COMMAND: found 'frobnicate', expected one of calibrate, simulate"),
    ],
    ids=["no value", "method", "choice", "ambiguous", "value for a switch", "exclusive",
         "required", "command"],
)
def test_argparse_failures_in_one_form(argv: list[str], match: str, csv_path: Path,
                                       tmp_path: Path, refusals: Refusals) -> None:
    """argparse's messages rewritten as `FLAG: found X, expected Y` (choices listed)."""
    refusals.cli([arg.format(csv=csv_path, tmp=tmp_path) for arg in argv], [csv_path, tmp_path],
                 match)


@pytest.mark.parametrize(
    ("distances", "match"),
    [
        (["a,b=50", "b,a=60"], "--distance: found b,a a second time (50 mm, then 60 mm), "
         "expected each pair of points once"),
        (["a,b=50", "a,b=50"], "--distance: found a,b a second time (50 mm, then 50 mm)"),
        (["a,a=50"], "--distance: found 'a,a=50', expected A,B=MM: two different point names"),
    ],
)
def test_contradictory_known_distances(distances: list[str], match: str, csv_path: Path,
                                       refusals: Refusals) -> None:
    """A pair told twice (with two lengths, or the same) and a point's distance to itself."""
    flags = [item for value in distances for item in ("--distance", value)]
    refusals.cli(["calibrate", csv_path, "--port", PORT, *flags], [csv_path], match)


def test_contradictory_distances_in_a_capture(csv_path: Path, tmp_path: Path,
                                              irb120: RobotModel, refusals: Refusals) -> None:
    """The same in a capture's [rig] distances, named as its entry (not as --distance)."""
    (tmp_path / "robot.toml").write_text(robot_to_toml(irb120))
    capture = tmp_path / "capture.toml"
    write_capture(capture, robot="robot.toml", port_m=[0.6, -0.4, 0.1],
                  measurements=csv_path.name)
    capture.write_text(capture.read_text() + '\n[rig]\ndistances = ["p,q=50", "q,p=51"]\n')
    refusals.cli(["calibrate", capture], [tmp_path],
                 f"{capture}: [rig] distances[1]: found q,p a second time (50 mm, then 51 mm)")


@pytest.mark.parametrize("tolerance", ["1e9%", "101%", "inf%", "nan"])
def test_a_tolerance_beyond_100_percent(tolerance: str, tmp_path: Path,
                                        refusals: Refusals) -> None:
    """`--tolerance 1e9%` allowed any regression: at most 100 % (a metric twice as bad)."""
    refusals.cli(["check", SCENARIO, "--out", tmp_path / "out", f"--tolerance={tolerance}"],
                 [SCENARIO], f"--tolerance: found {tolerance!r}, expected a relative tolerance "
                 "from 0 to 100%")
    assert not (tmp_path / "out").exists()
