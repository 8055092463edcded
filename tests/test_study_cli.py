"""`twin study` as a user runs it: interrupted twice, resumed, every trial counted once."""

from __future__ import annotations

import io
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from test_study import recorded, with_study, write_scenario

TRIALS = 16
METHODS = ("lm", "pso", "bipso")
POLL_S = 0.05
WAIT_S = 240.0


def start(scenario: Path, out: Path) -> subprocess.Popen[bytes]:
    """`python -m twin study` in its own process group."""
    return subprocess.Popen([sys.executable, "-m", "twin", "study", str(scenario), "--out",
                             str(out)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            start_new_session=True)


def wait_for_more_than(out: Path, count: int, process: subprocess.Popen[bytes]) -> int:
    """Wait until more than ``count`` trials are recorded; returns how many are."""
    deadline = time.monotonic() + WAIT_S
    while time.monotonic() < deadline:
        done = len(recorded(out))
        if done > count:
            return done
        assert process.poll() is None, process.stderr.read().decode() if process.stderr else ""
        time.sleep(POLL_S)
    raise AssertionError(f"no trial beyond {count} within {WAIT_S} s")


@pytest.mark.slow
def test_interrupted_and_killed_runs_resume_to_every_trial_once(tmp_path: Path) -> None:
    """Ctrl-C (SIGINT) stops a run with exit code 130; SIGKILL of the whole process group stops
    another mid-write if it must; the third run finishes the rest. Each trial then has one row
    per method, the tables and figures are written, and the progress bars (the trials', then
    the figures') reached their totals."""
    methods = ", ".join(f'"{m}"' for m in METHODS)
    scenario = write_scenario(tmp_path, with_study(f"trials = {TRIALS}\nmethods = [{methods}]"))
    out = tmp_path / "out"

    first = start(scenario, out)
    wait_for_more_than(out, 0, first)
    first.send_signal(signal.SIGINT)
    assert first.wait(timeout=60) == 130
    after_first = recorded(out)
    print(f"after SIGINT: {len(after_first)} of {TRIALS} trials")
    assert 0 < len(after_first) < TRIALS

    second = start(scenario, out)
    wait_for_more_than(out, len(after_first), second)
    os.killpg(second.pid, signal.SIGKILL)
    second.wait(timeout=60)
    after_second = recorded(out)
    print(f"after SIGKILL: {len(after_second)} of {TRIALS} trials")
    assert len(after_first) < len(after_second) < TRIALS

    third = subprocess.run([sys.executable, "-m", "twin", "study", str(scenario), "--out",
                            str(out)], capture_output=True, text=True, timeout=WAIT_S)
    assert third.returncode == 0, third.stderr
    assert recorded(out) == {trial: len(METHODS) for trial in range(TRIALS)}
    assert f"{TRIALS}/{TRIALS} trials" in third.stderr
    # The figures (a second each) come after the trials with a bar of their own.
    assert third.stderr.index("0/4 figures") > third.stderr.index(f"{TRIALS}/{TRIALS} trials")
    assert "4/4 figures" in third.stderr
    summary = (out / "summary.md").read_text()
    assert "Table 6 replica" in summary and "M9 (AMLM-BIPSO) is not in this study" in summary
    assert "Table 6 replica" in third.stdout
    for name in ("fig3_metrics.png", "fig4_convergence.png", "fig5_residuals.png",
                 "parameter_error.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.slow
def test_rerun_recording_holds_each_trial_and_the_summary(tmp_path: Path) -> None:
    """With --rerun-save, each trial's table is logged on the `trial` timeline as it lands and
    the summary as the report; the .rrd is read back with Rerun's own reader."""
    from rerun.chunk import RrdReader

    from twin.cli import main

    scenario = write_scenario(tmp_path, with_study('trials = 3\nmethods = ["lm"]'))
    recording = tmp_path / "study.rrd"
    assert main(["study", str(scenario), "--out", str(tmp_path / "out"),
                 "--rerun-save", str(recording)]) == 0
    texts: dict[str, list[tuple[int, str]]] = {}
    curves: dict[str, list[float]] = {}
    for chunk in RrdReader(recording).stream().to_chunks():
        batch = chunk.to_record_batch()
        if "Scalars:scalars" in batch.schema.names:
            curves.setdefault(chunk.entity_path.lstrip("/"), []).extend(
                v[0] for v in batch.column("Scalars:scalars").to_pylist())
        if "TextDocument:text" not in batch.schema.names:
            continue
        trials = batch.column("trial").to_pylist() if "trial" in batch.schema.names \
            else [-1] * batch.num_rows
        values = [v[0] for v in batch.column("TextDocument:text").to_pylist()]
        texts.setdefault(chunk.entity_path.lstrip("/"), []).extend(zip(trials, values,
                                                                        strict=True))
    assert sorted(t for t, _ in texts["study/trial"]) == [0, 1, 2]
    assert all(text.startswith(f"### Trial {t}") and "| lm |" in text
               for t, text in texts["study/trial"])
    # Each trial's convergence curve, equal to the history the study stored for it.
    details = [json.loads(line) for line in (tmp_path / "out" / "trials.jsonl").read_text()
               .splitlines()]
    for detail in details:
        history = detail["methods"]["lm"]["history_mm"]
        assert curves[f"convergence/lm/trials/{detail['trial']}"] == history
    assert len(details) == 3
    ((_, report),) = texts["report"]
    assert "Table 6 replica" in report and report == (tmp_path / "out" / "summary.md").read_text()


@pytest.mark.slow
def test_no_figures_then_a_second_run_draws_them_running_no_trial(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`twin study --no-figures` writes the tables and no PNG; `twin study` of the same folder
    then draws them and runs no trial (results.csv byte for byte as it was)."""
    from twin.cli import main

    scenario = write_scenario(tmp_path, with_study('trials = 2\nmethods = ["lm"]'))
    out = tmp_path / "out"
    argv = ["study", str(scenario), "--out", str(out)]
    assert main([*argv, "--no-figures"]) == 0
    assert (out / "summary.md").exists() and not list(out.glob("*.png"))
    assert "written: " in capsys.readouterr().err
    results = (out / "results.csv").read_bytes()
    assert main(argv) == 0
    assert (out / "results.csv").read_bytes() == results
    assert sorted(path.name for path in out.glob("*.png")) == [
        "fig3_metrics.png", "fig4_convergence.png", "fig5_residuals.png", "parameter_error.png"]
    assert "fig3_metrics.png" in capsys.readouterr().err


@pytest.mark.parametrize("kernel", ["Numba", "compiled"])
def test_a_kernel_that_names_none_is_refused_before_the_folder_exists(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
        kernel: str) -> None:
    """A TWIN_KERNEL that names no kernel is the command's one line before anything is
    written: it had created the study's folder, results.csv and study.json, and failed at the
    first trial."""
    from twin.choices import KERNEL_VARIABLE
    from twin.cli import main

    scenario = write_scenario(tmp_path, with_study('trials = 1\nmethods = ["lm"]'))
    monkeypatch.setenv(KERNEL_VARIABLE, kernel)
    out = tmp_path / "out"
    assert main(["study", str(scenario), "--out", str(out)]) == 2
    assert capsys.readouterr().err == (f"twin: error: TWIN_KERNEL: found unknown kernel "
                                       f"{kernel!r}, expected one of auto, numba, numpy\n")
    assert not out.exists()


@pytest.mark.slow
def test_figures_drawn_on_forked_workers_are_those_drawn_here(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """With local processes forked from the command (Linux), a study's figures are drawn on the
    workers, in processes other than this one, and written here byte for byte as this process
    draws them."""
    from twin.cli import main
    from twin.study import figures
    from twin.study.definition import load_study
    from twin.study.executors.local import LocalProcesses
    from twin.study.runner import write_report
    from twin.study.store import open_store

    executor = LocalProcesses(2)
    if not executor.forks:
        pytest.skip("workers are spawned on this platform: the figures are drawn here")
    scenario = write_scenario(tmp_path, with_study('trials = 2\nmethods = ["lm"]'))
    out = tmp_path / "out"
    assert main(["study", str(scenario), "--out", str(out), "--no-figures"]) == 0
    plan = load_study(scenario)
    store = open_store(plan, out)
    drawers = tmp_path / "drawers"  # a file per process that rendered a figure, named by pid
    drawers.mkdir()
    render = figures.png_bytes

    def noted(figure: object) -> bytes:
        (drawers / str(os.getpid())).touch()
        return render(figure)

    monkeypatch.setattr(figures, "png_bytes", noted)  # forked workers inherit it
    write_report(plan, store, stream=io.StringIO())
    here = {path.name: path.read_bytes() for path in out.glob("*.png")}
    assert len(here) == 4 and [path.name for path in drawers.iterdir()] == [str(os.getpid())]
    (drawers / str(os.getpid())).unlink()
    write_report(plan, store, stream=io.StringIO(), executor=executor)
    assert {path.name: path.read_bytes() for path in out.glob("*.png")} == here
    pids = {path.name for path in drawers.iterdir()}
    assert pids and str(os.getpid()) not in pids
