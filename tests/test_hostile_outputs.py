"""Hostile inputs, class 7 — outputs: no command loses a real capture or another run's rows.

Two outputs of one command at the same place are refused before any work; `twin simulate`
does not write over a folder of real measurements unless told (`--force`), and even then
moves them aside instead of deleting them; no output file replaces a capture's journal; a
folder is written by one command at a time (the second is told who holds it, in one line); a
failure leaves no lock; a killed run's temporary files are removed by the next; SIGTERM stops
a command as Ctrl-C does. Every case that runs a process has a timeout.
"""

from __future__ import annotations

import fnmatch
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import Refusals, snapshot
from test_capture import SCENARIO, SETTLE, Device

from twin.cli import main
from twin.io.atomic import temporary_beside
from twin.io.capture_file import load_capture
from twin.io.lock import LOCK_NAME
from twin.io.measurements import load_measurements
from twin.io.paths import CAPTURE_FOLDER, STUDY_FOLDER
from twin.scenario import parse_scenario
from twin.sim import simulate, write_simulation

ROOT = Path(__file__).resolve().parents[1]
SIM_SCENARIO = ROOT / "scenarios" / "geometric_irb120.toml"
CSV = ROOT / "examples" / "irb120_lm" / "measurements.csv"
EXPECT = ROOT / "examples" / "check" / "lm_ekf.toml"
PORT = "600,-400,100"
PLAN = "q1,q2,q3,q4,q5,q6\n10,20,-30,40,50,60\n-20,10,20,30,-40,50\n30,-10,10,-30,20,-60\n"
TWIN = [sys.executable, "-m", "twin"]
TIMEOUT_S = 120.0
"""Far longer than any of these runs takes, far shorter than a hang."""


@pytest.fixture(scope="module")
def real_capture(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A capture folder as `twin capture` writes it, from the virtual encoder over a pty."""
    folder = tmp_path_factory.mktemp("real")
    (folder / "scenario.toml").write_text(SCENARIO)
    (folder / "plan.csv").write_text(PLAN)
    device = Device(folder / "scenario.toml", folder / "pose.json")
    try:
        run = subprocess.run([*TWIN, "capture", "--plan", folder / "plan.csv", "--encoder",
                              device.url, "--robot-source", "sim", "--scenario",
                              folder / "scenario.toml", "--pose-file", folder / "pose.json",
                              "--out", folder / "cap", *SETTLE], capture_output=True,
                             text=True, timeout=TIMEOUT_S, check=False)
    finally:
        device.stop()
    assert run.returncode == 0, run.stderr
    return folder / "cap"


@pytest.fixture()
def capture_copy(real_capture: Path, tmp_path: Path) -> Path:
    """A copy of the real capture for one test to attack."""
    return Path(shutil.copytree(real_capture, tmp_path / "cap"))


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        (["check", str(SIM_SCENARIO), "--out", "{tmp}/out", "--junit", "{tmp}/out",
          "--methods", "lm", "--trials", "1"],
         "--junit: found {tmp}/out, the same path as --out, expected an output of its own"),
        (["calibrate", str(CSV), "--port", PORT, "--json", "{tmp}/r.json", "--rerun-save",
          "{tmp}/r.json"], "--rerun-save: found {tmp}/r.json, the same path as --json"),
        (["calibrate", str(CSV), "--port", PORT, "--json", "{tmp}/r.json", "--rerun-save",
          "{tmp}/r.json/x.rrd"], "--rerun-save: found {tmp}/r.json/x.rrd, a path under the "
         "--json file"),
        (["identify", str(CSV), "--port", PORT, "--map", "{tmp}/x", "--json", "{tmp}/x"],
         "--json: found {tmp}/x, the same path as --map"),
        (["simulate", str(SIM_SCENARIO), "--out", "{tmp}/sim", "--rerun-save", "{tmp}/sim"],
         "--rerun-save: found {tmp}/sim, the same path as --out"),
        (["study", str(SIM_SCENARIO), "--out", "{tmp}/s", "--rerun-save", "{tmp}/link"],
         "--rerun-save: found {tmp}/link, the same path as --out"),
        (["check", str(SIM_SCENARIO), "--out", "{tmp}/out", "--junit",
          "{tmp}/out/results.csv", "--methods", "lm", "--trials", "1"],
         "--junit: found {tmp}/out/results.csv, a file the command writes into the --out "
         "folder, expected another name (the folder's own: results.csv"),
        (["check", str(SIM_SCENARIO), "--out", "{tmp}/out", "--junit", "{tmp}/out/summary.md",
          "--methods", "lm", "--trials", "1"],
         "--junit: found {tmp}/out/summary.md, a file the command writes into the --out"),
        (["simulate", str(SIM_SCENARIO), "--out", "{tmp}/sim", "--rerun-save",
          "{tmp}/sim/capture.toml"],
         "--rerun-save: found {tmp}/sim/capture.toml, a file the command writes into the "
         "--out folder"),
    ],
    ids=["junit=out", "json=rerun", "under json", "map=json", "simulate", "symlink",
         "junit=results", "junit=summary", "rerun=capture"],
)
def test_two_outputs_at_one_place(argv: list[str], match: str, tmp_path: Path,
                                  refusals: Refusals) -> None:
    """`twin check … --out out --junit out` ran the whole study, printed PASS, then failed:
    outputs that collide are refused before any work, naming both flags."""
    (tmp_path / "link").symlink_to(tmp_path / "s")
    refusals.cli([arg.format(tmp=tmp_path) for arg in argv], [tmp_path, CSV],
                 match.format(tmp=tmp_path))


def test_an_output_of_another_name_may_go_into_the_folder(tmp_path: Path) -> None:
    """A name the folder's command does not write is the user's to choose (`--junit
    DIR/junit.xml` beside the study's files): both are written."""
    out = tmp_path / "out"
    assert main(["check", str(SIM_SCENARIO), "--out", str(out), "--junit",
                 str(out / "junit.xml"), "--methods", "lm,ekf", "--trials", "1", "--expect",
                 str(EXPECT), "--no-figures"]) in (0, 1)
    assert (out / "junit.xml").read_text().startswith("<?xml")
    assert (out / "results.csv").read_text().startswith("trial,case,")
    assert _undeclared(out, STUDY_FOLDER) == ["junit.xml"]


def _undeclared(folder: Path, patterns: tuple[str, ...]) -> list[str]:
    """The names in ``folder`` that none of the patterns a command declares it writes match."""
    return sorted(path.name for path in folder.iterdir()
                  if not any(fnmatch.fnmatchcase(path.name, p) for p in patterns))


@pytest.mark.slow
def test_a_capture_folder_holds_only_what_its_commands_declare(
        real_capture: Path, capture_copy: Path, tmp_path: Path) -> None:
    """The names the CLI keeps other outputs from are every name `twin capture` and `twin
    simulate` (over a capture, with --force) write: nothing else appears in their folders."""
    assert _undeclared(real_capture, CAPTURE_FOLDER) == []
    assert main(["simulate", str(SIM_SCENARIO), "--out", str(capture_copy), "--force"]) == 0
    assert _undeclared(capture_copy, CAPTURE_FOLDER) == []


def test_two_outputs_hard_linked(tmp_path: Path, refusals: Refusals) -> None:
    """Two names of one file (a hard link) are one place too."""
    (tmp_path / "a.json").write_text("{}")
    os.link(tmp_path / "a.json", tmp_path / "b.rrd")
    refusals.cli(["calibrate", CSV, "--port", PORT, "--json", tmp_path / "a.json",
                  "--rerun-save", tmp_path / "b.rrd"], [tmp_path, CSV],
                 f"--rerun-save: found {tmp_path / 'b.rrd'}, the same path as --json")


@pytest.mark.slow
def test_simulate_over_a_real_capture_is_refused(capture_copy: Path,
                                                 refusals: Refusals) -> None:
    """It replaced the capture's measurements.csv with simulated data: now one line, exit 2,
    the folder byte for byte as it was."""
    refusals.cli(["simulate", SIM_SCENARIO, "--out", capture_copy], [capture_copy],
                 f"{capture_copy / 'measurements.csv'}: found a capture's measurements, "
                 "expected a folder without real measurements: a new --out folder, or --force")


@pytest.mark.slow
def test_simulate_with_force_moves_the_capture_aside(
        capture_copy: Path, real_capture: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """With --force the simulation is written, and the capture's files are moved, byte for
    byte, into kept-<time>/, where they still calibrate; nothing is deleted."""
    from twin.cli import main

    before = {Path(name).name: digest for name, digest in snapshot([real_capture]).items()}
    assert main(["simulate", str(SIM_SCENARIO), "--out", str(capture_copy), "--force"]) == 0
    warning = capsys.readouterr().err
    (kept,) = capture_copy.glob("kept-*")
    assert f"twin: warning: {capture_copy} held a capture's measurements: measurements.csv, " \
        f"plan.csv, capture.toml, robot.toml, truth.json moved to {kept}" in warning
    assert {Path(name).name: digest for name, digest in snapshot([kept]).items()} == before
    capture = load_capture(kept / "capture.toml")
    assert len(load_measurements(capture.measurements)) == PLAN.count("\n") - 1
    assert load_capture(capture_copy / "capture.toml").truth is not None
    assert not (capture_copy / LOCK_NAME).exists()


def test_simulate_over_measurements_no_simulation_wrote(tmp_path: Path,
                                                        refusals: Refusals) -> None:
    """A measurements.csv without the truth.json a simulation writes beside it is real data
    (a CSV copied from a cell): refused as well."""
    folder = tmp_path / "cell"
    folder.mkdir()
    shutil.copy(CSV, folder / "measurements.csv")
    refusals.cli(["simulate", SIM_SCENARIO, "--out", folder], [folder],
                 f"{folder / 'measurements.csv'}: found measurements no simulation wrote")


def test_simulate_over_a_simulation_is_allowed(tmp_path: Path) -> None:
    """Another simulation's folder is replaced as before: its data are simulated."""
    from twin.cli import main

    folder = tmp_path / "sim"
    scenario = parse_scenario({"name": "s", "seed": 2, "port": {"position_mm": [600, -400, 100]},
                               "poses": {"count": 30}}, tmp_path / "s.toml")
    write_simulation(folder, simulate(scenario))
    assert main(["simulate", str(SIM_SCENARIO), "--out", str(folder)]) == 0
    assert sorted(path.name for path in folder.iterdir()) == [
        "capture.toml", "measurements.csv", "robot.toml", "truth.json"]


@pytest.mark.slow
def test_no_output_file_replaces_a_capture_journal(capture_copy: Path, tmp_path: Path,
                                                   refusals: Refusals) -> None:
    """`twin plan --out cap/measurements.csv`: the capture's journal is not an input of the
    command, and still never replaced."""
    journal = capture_copy / "measurements.csv"
    refusals.cli(["plan", "--port", PORT, "--poses", "30", "--joint-limits-only", "--out",
                  journal], [capture_copy], f"{journal}: found a capture's measurements")


def _study(folder: Path, trials: int, command: str = "study", *, group: bool = False
           ) -> subprocess.Popen[str]:
    """`twin study` (or `twin check`, of an LM expectation) of LM trials, as a process (the
    leader of a process group of its own if ``group``), without figures (what is checked is
    the rows, the lock and the temporary files; drawing was a third of a short run)."""
    argv = [*TWIN, command, str(SIM_SCENARIO), "--out", str(folder), "--trials", str(trials),
            "--methods", "lm", "--no-figures"]
    if command == "check":
        expect = folder.parent / "expect.toml"
        expect.write_text('[expect]\nlm = ["converged share >= 0.5"]\n')
        argv += ["--expect", str(expect)]
    return subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=group)


def _wait_for(path: Path, process: subprocess.Popen[str], lines: int = 0) -> None:
    """Until ``path`` exists (with more than ``lines`` lines), while ``process`` runs."""
    deadline = time.monotonic() + TIMEOUT_S
    while not (path.exists() and path.read_text().count("\n") > lines):
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline, f"{path} never came"
        time.sleep(0.05)


def _rows(folder: Path) -> list[tuple[str, str]]:
    """The (trial, method) of every row of a study's results.csv."""
    lines = (folder / "results.csv").read_text().splitlines()[1:]
    return [(line.split(",")[0], line.split(",")[3]) for line in lines]


@pytest.mark.slow
@pytest.mark.parametrize("second", ["study", "check"])
def test_a_second_writer_of_a_study_folder(second: str, tmp_path: Path) -> None:
    """Two `twin study --out same` at once both exited 0 with 48 duplicated rows. Now the
    second (a study or a check) says in one line who holds the folder and exits 2, writing
    nothing; the first, stopped later, has every trial at most once and leaves no lock."""
    folder = tmp_path / "study"
    first = _study(folder, 5000)
    try:
        _wait_for(folder / "results.csv", first, lines=1)
        late = _study(folder, 5000, second)
        _, error = late.communicate(timeout=TIMEOUT_S)
    finally:
        first.send_signal(signal.SIGTERM)
        _, first_error = first.communicate(timeout=TIMEOUT_S)
    assert late.returncode == 2, error
    assert error.count("\n") == 1 and "Traceback" not in error, error
    assert error.startswith(f"twin: error: {folder}: found another command writing this folder "
                            f"(twin study, pid {first.pid} on host ")
    assert first.returncode == 143, first_error
    rows = _rows(folder)
    assert len(rows) == len(set(rows))
    assert not (folder / LOCK_NAME).exists()


@pytest.mark.slow
def test_two_studies_started_together_never_duplicate_a_row(tmp_path: Path) -> None:
    """Started at the same moment: whichever gets the folder runs; the other is refused, or
    (if the first was already done) finds nothing left to run. Never a row twice."""
    folder = tmp_path / "study"
    runs = [_study(folder, 8) for _ in range(2)]
    outputs = [run.communicate(timeout=TIMEOUT_S) for run in runs]
    codes = sorted(run.returncode for run in runs)
    assert codes in ([0, 0], [0, 2]), outputs
    rows = _rows(folder)
    assert len(rows) == len(set(rows)) == 8
    assert not (folder / LOCK_NAME).exists()


@pytest.mark.slow
def test_an_early_failure_leaves_no_lock(tmp_path: Path, refusals: Refusals) -> None:
    """A capture whose encoder cannot be opened (a fault, exit 1) left its new folder with a
    `.lock`; a study refused by the folder it was pointed at leaves it as it was."""
    plan = tmp_path / "plan.csv"
    plan.write_text(PLAN)
    refusals.process(["capture", "--plan", plan, "--encoder", "serial:///dev/nonexistent",
                      "--robot-source", "manual", "--port", PORT, "--out", tmp_path / "new"],
                     [plan], "cannot open encoder port /dev/nonexistent", code=1,
                     timeout=TIMEOUT_S)
    assert not (tmp_path / "new").exists()
    other = tmp_path / "other"
    other.mkdir()
    (other / "study.json").write_text('{"fingerprint": "another study"}')
    refusals.cli(["study", SIM_SCENARIO, "--out", other, "--trials", "1", "--methods", "lm"],
                 [other], "found a study in")


@pytest.mark.slow
def test_a_killed_runs_temporary_files_are_removed(tmp_path: Path) -> None:
    """A process killed (SIGKILL) between creating a temporary file and renaming it leaves
    `.summary.md.<pid>-….tmp`; the next study of the folder removes it, and leaves alone the
    temporary file of a process that still runs."""
    folder = tmp_path / "study"
    folder.mkdir()
    code = ("import sys, time\nfrom twin.io.atomic import temporary_beside\n"
            f"print(temporary_beside({str(folder / 'summary.md')!r}), flush=True)\n"
            "time.sleep(600)\n")
    writer = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    assert writer.stdout is not None
    stale = Path(writer.stdout.readline().strip())
    writer.send_signal(signal.SIGKILL)
    writer.wait(timeout=TIMEOUT_S)
    live = temporary_beside(folder / "summary.json")  # this process's: it is alive
    assert stale.exists() and stale.name.startswith(f".summary.md.{writer.pid}-")
    run = subprocess.run([*TWIN, "study", str(SIM_SCENARIO), "--out", str(folder), "--trials",
                          "1", "--methods", "lm", "--no-figures"], capture_output=True, text=True,
                         timeout=TIMEOUT_S, check=False)
    assert run.returncode == 0, run.stderr
    assert not stale.exists() and live.exists()
    assert sorted(path.name for path in folder.glob(".*")) == [live.name]


@pytest.mark.slow
def test_sigterm_stops_a_study_as_ctrl_c(tmp_path: Path) -> None:
    """SIGTERM mid-study: exit 143 with one line, no lock and no temporary file left, every
    recorded trial whole; the same study then resumes, each trial once."""
    folder = tmp_path / "study"
    study = _study(folder, 5000)
    _wait_for(folder / "results.csv", study, lines=2)
    study.send_signal(signal.SIGTERM)
    _, error = study.communicate(timeout=TIMEOUT_S)
    assert study.returncode == 143, error
    assert error.endswith("twin: terminated\n") and "Traceback" not in error, error
    assert sorted(path.name for path in folder.glob(".*")) == []
    done = _rows(folder)
    assert 0 < len(done) == len(set(done))
    finish = _study(folder, 10)
    finish.communicate(timeout=TIMEOUT_S)
    assert finish.returncode == 0
    rows = _rows(folder)
    assert len(rows) == len(set(rows))
    assert set(rows) == set(done) | {(str(trial), "lm") for trial in range(10)}


@pytest.mark.slow
@pytest.mark.parametrize("command", ["study", "check"])
def test_sigterm_to_the_process_group_stops_workers_quietly(command: str,
                                                          tmp_path: Path) -> None:
    """A supervisor (`timeout`, systemd, a CI job) stops the whole process group: the workers
    printed a traceback each, and 2 runs in 9 never exited. Now: exit 143, one line, every
    recorded trial whole, no worker left."""
    folder = tmp_path / "study"
    study = _study(folder, 5000, command, group=True)
    _wait_for(folder / "results.csv", study, lines=2)
    os.killpg(study.pid, signal.SIGTERM)
    _, error = study.communicate(timeout=TIMEOUT_S)
    assert study.returncode == 143, error
    assert error.endswith("\ntwin: terminated\n") and "Traceback" not in error, error
    done = _rows(folder)
    assert 0 < len(done) == len(set(done))
    deadline = time.monotonic() + TIMEOUT_S
    while True:  # the group is empty once every worker has exited
        try:
            os.killpg(study.pid, 0)
        except ProcessLookupError:
            break
        assert time.monotonic() < deadline, "a worker outlived the command"
        time.sleep(0.05)
