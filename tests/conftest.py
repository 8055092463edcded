"""Shared fixtures: the IRB 120, a known perturbation and data made by the core's model; and
:class:`Refusals`, which holds the CLI to its promise on a user's mistake."""

from __future__ import annotations

import hashlib
import os
import socket
import stat
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from twin.dataset import Measurements
from twin.geometry import kinematics
from twin.geometry.kinematics import KERNEL_VARIABLE
from twin.io.measurements import write_measurements
from twin.io.robot_file import default_robot
from twin.robot import RobotModel, random_poses
from twin.synthetic import synthesize
from twin.units import dh_rows_from_display, mm_to_m

PORT_M = mm_to_m([600.0, -400.0, 100.0])
TRUE_DELTA = dh_rows_from_display(
    {
        "a": [0.5, -0.8, 0.6, 0.3, -0.4, 0.2],
        "d": [0.7, 0.4, -0.6, 0.5, 0.3, -0.5],
        "alpha": [0.1, -0.2, 0.15, -0.1, 0.2, 0.1],
        "theta": [0.2, 0.1, -0.15, 0.1, -0.2, 0.05],
    }
)
"""A known perturbation, shape (4, 6), m and rad: about 1.3 mm RMSE on the cable."""


@pytest.fixture(autouse=True)
def _kernel_choice_restored() -> Any:
    """Every test starts on the kernel a single command takes: a test that runs a study's
    trials in this process declares bulk work (:func:`twin.geometry.kinematics.for_bulk_work`),
    which would leave every later test of its worker on the compiled kernel, whose round-off
    can move a fit on a flat valley (the MUKCa cross-validation block's fourth digit)."""
    bulk = kinematics._BULK[0]
    yield
    if kinematics._BULK[0] != bulk:
        kinematics._BULK[0] = bulk
        kinematics._compiled.cache_clear()


@pytest.fixture
def kernel(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch):  # type: ignore[no-untyped-def]
    """The kernels taken for the test (parametrised indirectly): ``numpy`` (the reference path)
    or ``numba`` (the compiled kernels of the extra ``fast``)."""
    if request.param == "numba":
        pytest.importorskip("numba")
    monkeypatch.setenv(KERNEL_VARIABLE, request.param)
    kinematics._compiled.cache_clear()
    assert kinematics.takes_compiled() == (request.param == "numba")
    yield request.param
    monkeypatch.delenv(KERNEL_VARIABLE)
    kinematics._compiled.cache_clear()


@pytest.fixture(scope="session")
def port_m() -> np.ndarray:
    """The encoder port of the core-made data, shape (3,), m."""
    return PORT_M


@pytest.fixture(scope="session")
def true_delta() -> np.ndarray:
    """The known perturbation of the core-made data, shape (4, 6), m and rad."""
    return TRUE_DELTA


@pytest.fixture(scope="session")
def irb120() -> RobotModel:
    return default_robot()


@pytest.fixture(scope="session")
def true_robot(irb120: RobotModel) -> RobotModel:
    return irb120.perturbed(TRUE_DELTA)


@pytest.fixture()
def csv_path(measurements: Measurements, tmp_path: Path) -> Path:
    """The core-made measurements written as a CSV file (degrees, mm)."""
    path = tmp_path / "measurements.csv"
    write_measurements(path, measurements)
    return path


@pytest.fixture(scope="session")
def measurements(irb120: RobotModel, true_robot: RobotModel) -> Measurements:
    """120 poses of the perturbed robot, σ = 0.01 mm, seeded."""
    rng = np.random.default_rng(7)
    return synthesize(true_robot, random_poses(irb120, 120, rng), PORT_M, 1e-5, rng)


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on now."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def snapshot(paths: Sequence[Path]) -> dict[str, str]:
    """What must not change: the SHA-256 of every regular file at or under the paths (the
    folders' listings included, hidden files too), the type and device number of the rest."""
    found: dict[str, str] = {}
    for path in paths:
        files = sorted(path.rglob("*")) if path.is_dir() else [path]
        for item in files:
            info = os.stat(item) if item.exists() else None
            if info is None:
                found[str(item)] = "missing"
            elif stat.S_ISREG(info.st_mode):
                found[str(item)] = hashlib.sha256(item.read_bytes()).hexdigest()
            else:
                found[str(item)] = f"mode {stat.S_IFMT(info.st_mode):o}, device {info.st_rdev}"
    return found


class Refusals:
    """Runs the CLI on a user's mistake and checks the promise: the exit code (2 unless told),
    exactly one line on stderr, ``twin: error: …`` naming what was wrong, no traceback, and
    every input byte for byte as it was (folders: no file added, removed or changed)."""

    def __init__(self, capsys: pytest.CaptureFixture[str]) -> None:
        self.capsys = capsys

    def cli(self, argv: Sequence[Any], inputs: Sequence[Path], match: str,
            code: int = 2) -> str:
        """Run ``twin.cli.main`` in this process; returns the error line."""
        from twin.cli import main

        before = snapshot(inputs)
        self.capsys.readouterr()
        assert main([str(arg) for arg in argv]) == code
        error = self.capsys.readouterr().err
        self._check(error, match, before, inputs)
        return error

    def process(self, argv: Sequence[Any], inputs: Sequence[Path], match: str, code: int = 2,
                timeout: float = 60.0, **popen: Any) -> str:
        """Run ``python -m twin`` as a process that must end within ``timeout`` seconds (a
        hang fails the test instead of hanging it); returns the error line."""
        before = snapshot(inputs)
        run = subprocess.run([sys.executable, "-m", "twin", *map(str, argv)],
                             capture_output=True, text=True, timeout=timeout, check=False,
                             stdin=subprocess.DEVNULL, **popen)
        assert run.returncode == code, run.stderr
        self._check(run.stderr, match, before, inputs)
        return run.stderr

    @staticmethod
    def _check(error: str, match: str, before: dict[str, str], inputs: Sequence[Path]) -> None:
        assert "Traceback" not in error, error
        assert error.startswith("twin: error: ") and error.count("\n") == 1, error
        assert match in error, error
        assert snapshot(inputs) == before


@pytest.fixture()
def refusals(capsys: pytest.CaptureFixture[str]) -> Refusals:
    """See :class:`Refusals`."""
    return Refusals(capsys)
