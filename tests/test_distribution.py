"""The distribution's name and version, as `twin --version` reports them."""

from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_version_names_the_distribution_and_the_version_it_declares() -> None:
    """`twin --version` prints the distribution name and version of pyproject.toml, read from
    the installed metadata, and exits with code 0."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    twin = Path(sys.executable).with_name("twin")
    done = subprocess.run([str(twin), "--version"], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout == f"{project['name']} {project['version']}\n"


ADAPTER_LIBRARIES = ("mujoco", "pinocchio", "rerun", "serial", "minimalmodbus", "pymodbus",
                     "requests", "rosbags", "dask", "distributed")
EXAMPLE = ROOT / "examples" / "irb120_lm" / "measurements.csv"
PORT = "600,-400,100"


def run_without(blocked: tuple[str, ...], argv: list[str]) -> subprocess.CompletedProcess[str]:
    """`twin ARGV` in a fresh interpreter where importing any of ``blocked`` fails, as it does
    when its extra is not installed."""
    code = ("import sys\n"
            f"for name in {blocked!r}:\n    sys.modules[name] = None\n"
            "from twin.cli import main\n"
            f"sys.exit(main({argv!r}))\n")
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=False, cwd=ROOT)


@pytest.mark.slow
def test_the_core_install_calibrates(tmp_path: Path) -> None:
    """With every adapter library absent, `twin calibrate` runs and writes its result."""
    out = tmp_path / "result.json"
    done = run_without(ADAPTER_LIBRARIES, ["calibrate", str(EXAMPLE), "--port", PORT,
                                           "--json", str(out)])
    assert done.returncode == 0, done.stderr
    assert out.is_file() and "validation" in done.stdout


@pytest.mark.slow
def test_a_command_without_its_extra_names_the_extra(tmp_path: Path) -> None:
    """A command whose adapter library is absent ends with one line naming the extra to
    install and exits with code 2, without a traceback; a study fails before its folder."""
    result = tmp_path / "result.json"
    assert run_without((), ["calibrate", str(EXAMPLE), "--port", PORT,
                            "--json", str(result)]).returncode == 0
    plan = tmp_path / "plan.csv"
    plan.write_text("q1,q2,q3,q4,q5,q6\n0,0,0,0,30,0\n")
    cases = [
        ("mujoco", "sim", ["simulate", str(ROOT / "scenarios" / "geometric_irb120.toml"),
                           "--out", str(tmp_path / "sim")]),
        ("rerun", "viz", ["calibrate", str(EXAMPLE), "--port", PORT,
                          "--rerun-save", str(tmp_path / "run.rrd")]),
        ("pinocchio", "pinocchio", ["identify", str(EXAMPLE), "--port", PORT,
                                    "--robot", str(ROOT / "models" / "ur5e" / "ur5e.urdf")]),
        ("serial", "hardware", ["capture", "--plan", str(plan), "--encoder", "serial:///dev/null",
                                "--robot-source", "manual", "--port", PORT,
                                "--out", str(tmp_path / "capture")]),
        ("requests", "hardware", ["capture", "--plan", str(plan), "--encoder",
                                  "serial:///dev/null", "--robot-source", "rws://127.0.0.1:9",
                                  "--port", PORT, "--out", str(tmp_path / "rws")]),
        ("dask", "cluster", ["study", str(ROOT / "scenarios" / "geometric_irb120.toml"),
                             "--out", str(tmp_path / "study"), "--trials", "1",
                             "--methods", "lm", "--workers", "1"]),
    ]
    for library, extra, argv in cases:
        done = run_without((library,), argv)
        assert done.returncode == 2, (library, done.stderr)
        assert "Traceback" not in done.stderr, done.stderr
        assert done.stderr.splitlines()[-1] == (
            f"twin: error: {argv[0]}: found no module {library!r}, expected the optional extra "
            f"that installs it: pip install 'cabletwin[{extra}]'"), library
    assert not (tmp_path / "study").exists()
