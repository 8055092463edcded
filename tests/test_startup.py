"""`twin --version` and `twin CMD --help` answer without loading numpy, scipy or an adapter's
library: each command imports what it uses when it runs (twin/cli/, twin/__init__.py)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from twin.cli import SUBCOMMANDS
from twin.distribution import EXTRAS

HEAVY = sorted({"numpy", "scipy", "matplotlib", "ssl", *EXTRAS})
"""Libraries a command loads only when it runs (ssl too, which any importer of urllib.request
pulls in: 48 ms of twin --version when the RWS protocol module imported xml.sax.saxutils)."""


def _loaded_after(calls: list[list[str]], libraries: list[str] = HEAVY
                  ) -> dict[str, list[str]]:
    """Run ``twin.cli.main`` on each argument list, each in a fresh interpreter; which of
    ``libraries`` (the heavy ones by default) each left in ``sys.modules``."""
    found = {}
    for argv in calls:
        code = ("import contextlib, io, json, sys\n"
                "from twin.cli import main\n"
                "with contextlib.redirect_stdout(io.StringIO()), "
                "contextlib.redirect_stderr(io.StringIO()):\n"
                "    try:\n"
                f"        main({argv!r})\n"
                "    except SystemExit:\n"
                "        pass\n"
                f"print(json.dumps(sorted(m for m in {libraries!r} if m in sys.modules)))")
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                              check=True)
        found[" ".join(argv)] = json.loads(done.stdout)
    return found


@pytest.mark.slow
def test_version_and_every_help_load_no_heavy_library() -> None:
    """--version, the command list and each command's --help leave numpy, scipy, matplotlib
    and every adapter's library unloaded."""
    calls = [["--version"], ["--help"], *([module.NAME, "--help"] for module in SUBCOMMANDS)]
    loaded = _loaded_after(calls)
    assert set(loaded) == {" ".join(call) for call in calls}
    assert {call: libraries for call, libraries in loaded.items() if libraries} == {}


@pytest.mark.slow
def test_a_command_that_runs_loads_what_it_uses() -> None:
    """The check above can fail: a command that runs (here one that fails on its input after
    parsing) does load numpy; numba it leaves to bulk work (tests/test_compiled.py)."""
    loaded = _loaded_after([["predict", "--identified", "/nonexistent.json", "--joints",
                             "/nonexistent.csv", "--out", "/tmp/twin-startup-unused.csv"]])
    libraries = next(iter(loaded.values()))
    assert "numpy" in libraries and "numba" not in libraries


@pytest.mark.slow
def test_the_package_is_lazy_and_its_names_resolve() -> None:
    """`import twin` loads no numpy; reading a public name imports its module."""
    code = ("import sys, twin\n"
            "before = 'numpy' in sys.modules\n"
            "calibrate = twin.calibrate\n"
            "print(before, 'numpy' in sys.modules, calibrate.__module__)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    assert done.stdout.split() == ["False", "True", "twin.calibration.pipeline"]


SCIPY = ["scipy", "scipy.linalg", "scipy.optimize", "scipy.spatial", "scipy.special"]
"""scipy and the parts of it a command may load (0.15-0.3 s each, with what each pulls in)."""


@pytest.mark.slow
def test_a_command_loads_only_the_scipy_it_runs(tmp_path: Path) -> None:
    """The README's `twin calibrate` (LM, its checks and report) runs scipy's special
    functions (the fit test's χ² quantile), but neither its linear algebra (numpy's, and the
    pivoted QR of :func:`twin.analysis.identifiability.pivot_columns`: scipy.linalg was 0.1 s
    more to import), nor turns a rotation vector through ``scipy.spatial`` nor fits through
    ``scipy.optimize``; `twin predict` and `twin export` of its result run no
    scipy at all. Each part loads only where it runs (a third of calibrate's 0.8 s and half of
    predict's 0.4 s when they loaded with the modules that use them)."""
    example = Path(__file__).resolve().parents[1] / "examples" / "irb120_lm"
    result = tmp_path / "result.json"
    joints = tmp_path / "joints.csv"
    joints.write_text("q1,q2,q3,q4,q5,q6\n10,-20,30,40,50,60\n")
    calls = [["calibrate", str(example / "measurements.csv"), "--port", "600,-400,100",
              "--json", str(result)],
             ["predict", "--identified", str(result), "--joints", str(joints), "--out",
              str(tmp_path / "predicted.csv")],
             ["export", str(result), "--format", "dh", "--out", str(tmp_path / "dh.toml")]]
    loaded = _loaded_after(calls, SCIPY)
    assert [(tmp_path / name).is_file() for name in ("predicted.csv", "dh.toml")] == [True] * 2
    assert list(loaded.values()) == [["scipy", "scipy.special"], [], []]


def test_the_program_exits_without_a_last_collection(capsys: pytest.CaptureFixture[str]
                                                     ) -> None:
    """`twin` (the console script and ``python -m twin``) runs :func:`twin.cli.run`, which
    exits with the command's code once the command's objects are frozen out of the collector
    (the interpreter's last collection took 0.25 s after a study); :func:`twin.cli.main`, which
    a program calls and goes on, leaves the collector alone."""
    import gc
    import tomllib

    from twin.cli import main

    project = Path(__file__).resolve().parents[1] / "pyproject.toml"
    assert tomllib.loads(project.read_text())["project"]["scripts"]["twin"] == "twin.cli:run"
    assert main(["calibrate", "/nonexistent.csv", "--port", "1,2,3"]) == 2
    assert gc.get_freeze_count() == 0
    assert capsys.readouterr().err.startswith("twin: error: /nonexistent.csv")
    code = ("import atexit, gc, sys\n"
            "atexit.register(lambda: print('frozen', gc.get_freeze_count() > 0))\n"
            "sys.argv = ['twin', 'calibrate', '/nonexistent.csv', '--port', '1,2,3']\n"
            "from twin.cli import run\n"
            "run()")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=False)
    assert (done.returncode, done.stdout) == (2, "frozen True\n")
    assert done.stderr.startswith("twin: error: /nonexistent.csv")
