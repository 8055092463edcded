"""The real data set of examples/panda_mukca: its README's table is what its command prints."""

from __future__ import annotations

import importlib.util
import re
import shlex
import sys
from pathlib import Path

import pytest

from twin.cli import main

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "panda_mukca"


@pytest.mark.slow
def test_the_readme_command_reproduces_the_documented_table(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """evaluate.py, run afresh on the shipped files (imported by `twin import`), gives the
    README's table digit for digit (seeded, deterministic), and calibration removes most of the
    nominal model's held-out error on every placement."""
    spec = importlib.util.spec_from_file_location("mukca_evaluate", EXAMPLE / "evaluate.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, spec.name, module)
    spec.loader.exec_module(module)
    rows = module.evaluate(module.import_data(tmp_path))
    fresh = module.markdown_table(module.HEADER, rows)
    readme = (EXAMPLE / "README.md").read_text(encoding="utf-8")
    block = re.search(r"<!-- BEGIN GENERATED mukca -->\n(.*?)<!-- END GENERATED mukca -->",
                      readme, re.DOTALL)
    assert block is not None and fresh in block[1]
    assert re.search(r"Measured at commit `[0-9a-f]{7,}`", block[1])
    for row in rows[:3]:
        assert float(row[4]) < 0.2 * float(row[3])


def test_the_readme_commands_by_hand_give_the_tables_last_row(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """The README's `twin import` and `twin calibrate` lines, run as written (out/ moved under
    a temporary folder), print the table's random-split row: RMSE nominal and calibrated."""
    readme = (EXAMPLE / "README.md").read_text(encoding="utf-8")
    block = readme.split("The same data by hand", 1)[1].split("```sh\n", 1)[1].split("```")[0]
    lines = block.replace("\\\n", " ").splitlines()
    root = EXAMPLE.parents[1]
    monkeypatch.chdir(root)
    data = str(root / "examples" / "panda_mukca" / "data")
    commands = [shlex.split(line.replace("$D", data).replace("out/", f"{tmp_path}/"))
                for line in lines if line.startswith("$T ")]
    assert [command[1] for command in commands] == ["import", "calibrate"]
    for command in commands:
        expanded = [str(path) for word in command[2:]
                    for path in (sorted(Path("/").glob(word.lstrip("/"))) if "*" in word
                                 else [word])]
        assert main([command[1], *expanded]) == 0
    printed = capsys.readouterr().out
    before = re.search(r"before \(valid\.\)\s+(\S+)", printed)
    after = re.search(r"after, validation\s+(\S+)", printed)
    row = re.search(r"\| random 20 % of all \| the other 80 % \| \d+ \| (\S+) \| (\S+) \|",
                    readme)
    assert before and after and row
    assert (f"{float(before[1]):.3f}", f"{float(after[1]):.3f}") == (row[1], row[2])
