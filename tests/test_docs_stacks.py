"""docs/compensation.md's commands run: every `twin` line of its sh blocks from "Full-pose
targets" on, from the repository root, writing under out/ (a temporary folder here)."""

from __future__ import annotations

import re
import shlex
import subprocess
from pathlib import Path

import pytest

from twin.cli import main

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "compensation.md"


def _commands() -> list[str]:
    text = DOC.read_text(encoding="utf-8")
    text = text[text.index("## Full-pose targets"):]
    blocks = re.findall(r"```sh\n(.*?)```", text, re.S)
    return [line for block in blocks for line in block.splitlines() if line.strip()]


@pytest.mark.slow
def test_doc_commands_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Each command exits 0, in the order the page gives them (later ones read earlier ones'
    outputs)."""
    pytest.importorskip("pinocchio")
    pytest.importorskip("mujoco")
    monkeypatch.chdir(ROOT)
    out = tmp_path / "out"
    out.mkdir()
    commands = _commands()
    assert len(commands) >= 8
    # The calibration the page starts its stacks from comes first, whatever order they read in.
    first = next(c for c in commands if c.startswith("twin calibrate examples/"))
    for command in [first, *[c for c in commands if c != first]]:
        command = command.replace("out/", f"{out}/")
        if command.startswith("twin "):
            assert main(shlex.split(command)[1:]) == 0, command
        else:
            subprocess.run(command, shell=True, check=True, cwd=ROOT)
