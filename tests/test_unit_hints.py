"""Mistakes of the kind a user makes first: a file of another arm, values in the wrong unit."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import Refusals

from twin.cli import main

MODELS = Path(__file__).resolve().parents[1] / "models"


def test_more_joint_columns_than_the_robot_has(csv_path: Path, refusals: Refusals) -> None:
    """A 6-joint file with a 4-joint robot file: one line naming the column, exit 2."""
    refusals.cli(["calibrate", csv_path, "--robot", MODELS / "scara4" / "scara4.toml", "--port",
                  "600,-400,100"], [csv_path], "found the column q5 for a robot of 4 joints")


def test_a_port_in_metres_gets_a_hint(csv_path: Path, capsys: pytest.CaptureFixture[str]
                                      ) -> None:
    """--port 0.6,-0.4,0.1 (metres, as the API takes) beside lengths of hundreds of mm: a
    one-line hint naming the flag and the unit it probably is in (and the MISFIT)."""
    assert main(["calibrate", str(csv_path), "--port", "0.6,-0.4,0.1"]) == 0
    captured = capsys.readouterr()
    hint = [line for line in captured.err.splitlines() if "--port" in line]
    assert len(hint) == 1 and "looks like metres" in hint[0]
    assert "MISFIT" in captured.out
