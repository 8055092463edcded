"""Hostile inputs, class 3 — hangs: no input makes a command wait for ever unless asked to.

A FIFO with no writer blocks ``open()`` for ever, so only regular files are opened; a time
limit of ``nan`` or ``inf`` never expires, so time flags are finite (or an explicit ``none``).
Each case runs the CLI as a process with a timeout: a regression fails the test instead of
hanging it.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest
from conftest import Refusals

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "geometric_irb120.toml"
PORT = "600,-400,100"
TIMEOUT_S = 30.0
"""Far longer than a refusal takes (about a second to start Python), far shorter than never."""


@pytest.mark.parametrize(
    "argv",
    [
        ["calibrate", "{fifo}", "--port", PORT],
        ["calibrate", "{csv}", "--port", PORT, "--robot", "{fifo}"],
        ["simulate", "{fifo}", "--out", "{tmp}/out"],
        ["export", "{fifo}", "--format", "dh", "--out", "{tmp}/x.toml"],
        ["capture", "--plan", "{fifo}", "--encoder", "serial:///dev/null", "--robot-source",
         "manual", "--port", PORT, "--out", "{tmp}/out"],
    ],
    ids=["measurements", "robot model", "scenario", "result", "capture plan"],
)
@pytest.mark.slow
def test_a_fifo_without_a_writer(argv: list[str], csv_path: Path, tmp_path: Path,
                                 refusals: Refusals) -> None:
    """A FIFO given as an input file is refused at once, and stays a FIFO."""
    fifo = tmp_path / "input"
    os.mkfifo(fifo)
    paths = {"fifo": fifo, "csv": csv_path, "tmp": tmp_path}
    refusals.process([arg.format(**paths) for arg in argv], [csv_path, fifo],
                     f"{fifo}: found a FIFO, expected", timeout=TIMEOUT_S)
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("flag", "match"),
    [
        (["--reconnect", "nan"], "--reconnect: found 'nan', expected a time in [0, 86400] s, "
         "or none for no limit"),
        (["--settle-timeout", "inf"], "--settle-timeout: found 'inf', expected a time in (0, "
         "86400] s, or none for no limit"),
        (["--joint-log-wait", "inf"], "--joint-log-wait: found 'inf'"),
    ],
)
def test_a_time_limit_that_never_expires(flag: list[str], match: str, tmp_path: Path,
                                         refusals: Refusals) -> None:
    """`--reconnect nan` (after an unplug) and `--settle-timeout inf` (on a reading that never
    settles) would wait for ever: refused where they are parsed. Waiting for ever is
    `none`, said on purpose."""
    plan = tmp_path / "plan.csv"
    plan.write_text("q1,q2,q3,q4,q5,q6\n10,20,-30,40,50,60\n")
    refusals.process(["capture", "--plan", plan, "--encoder", "serial:///dev/null",
                      "--robot-source", "manual", "--port", PORT, "--out", tmp_path / "out",
                      *flag], [plan], match, timeout=TIMEOUT_S)
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_a_scheduler_that_does_not_answer(tmp_path: Path, refusals: Refusals) -> None:
    """An unreachable --scheduler is found out within the probe's timeout, before the study
    folder exists."""
    refusals.process(["study", SCENARIO, "--out", tmp_path / "study", "--scheduler",
                      "tcp://127.0.0.1:1"], [SCENARIO],
                     "--scheduler: found no scheduler reachable at tcp://127.0.0.1:1",
                     timeout=TIMEOUT_S)
    assert not (tmp_path / "study").exists()
