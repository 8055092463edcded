"""The real data set of examples/panda_mukca: its README's table is what its command prints."""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path

import pytest

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
