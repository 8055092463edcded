"""Every benchmark in bench/ runs to its end at its smoke size (``--tiny``), so that none can
crash unseen (bench_capture.py once did, on a changed signature), and leaves nothing behind in
the temporary folder or where it was run (bench_rerun.py left a folder of 0.2 MB in /tmp at
every run, CI's included); no timing is asserted. The docs generator (docs_tables.py) is run
by `make docs` and tests/test_docs_tables.py."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench"
SCRIPTS = sorted(path.name for path in BENCH.glob("bench_*.py"))


@pytest.mark.slow
@pytest.mark.parametrize("script", SCRIPTS)
def test_bench_script_runs_at_its_smoke_size(script: str, tmp_path: Path) -> None:
    """`python bench/SCRIPT --tiny` exits 0, prints something and leaves its temporary folder
    and its working folder as it found them (empty)."""
    temporary, working = tmp_path / "tmp", tmp_path / "work"
    temporary.mkdir()
    working.mkdir()
    done = subprocess.run([sys.executable, str(BENCH / script), "--tiny"], cwd=working,
                          env={**os.environ, "TMPDIR": str(temporary)}, capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.strip(), f"{script} printed nothing"
    left = sorted(str(path.relative_to(tmp_path)) for path in tmp_path.rglob("*")
                  if path not in (temporary, working))
    assert not left, f"{script} left {left}"


def test_every_script_is_smoke_tested() -> None:
    """The list above is every benchmark (a new one is run as soon as it exists)."""
    assert len(SCRIPTS) >= 12 and "bench_speed.py" in SCRIPTS
