"""The distribution's name and version, as `twin --version` reports them."""

from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_version_names_the_distribution_and_the_version_it_declares() -> None:
    """`twin --version` prints the distribution name and version of pyproject.toml, read from
    the installed metadata, and exits with code 0."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    twin = Path(sys.executable).with_name("twin")
    done = subprocess.run([str(twin), "--version"], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout == f"{project['name']} {project['version']}\n"
