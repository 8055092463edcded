"""Ground-truth files (`truth.json`) written by the twin beside a simulated capture (`twin
simulate`), or beside a capture measured with the virtual encoder (`twin capture
--robot-source sim`): :func:`write_truth` writes both.

The D-H error block ``"delta"`` is the same in a truth file and in a calibration result
(`twin calibrate --json`); :func:`parse_delta` reads it for both.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.errors import InputError
from twin.io.atomic import write_atomic
from twin.io.paths import read_json
from twin.io.table import Table
from twin.units import DH_KEYS, dh_rows_from_display, mm_to_m

TRUTH_FILE = "truth.json"
"""The truth file's name beside a capture."""


def write_truth(path: str | Path, document: Mapping[str, Any]) -> None:
    """Write a truth document (mm, degrees, arc-seconds; :attr:`twin.sim.Simulation.truth`)
    atomically as JSON."""
    write_atomic(path, json.dumps(dict(document), indent=2) + "\n")


def parse_delta(
    document: Any, n_joints: int, source: str | Path, where: str = "delta",
    is_length: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """The table errors under ``document["delta"]``, shape (4, n), m and rad.

    Args:
        document: A parsed JSON document (truth or result).
        n_joints: Number of joints n the robot has.
        source: The file, for the error message.
        where: Where ``document`` sits in the file, for the error message.
        is_length: Which entries are lengths, (4, n) (the robot's); D-H's rows if None.

    Raises:
        InputError: if there is no ``delta`` with lists a, d (mm), alpha, theta (deg) of n numbers.
    """
    block = document.get("delta") if isinstance(document, dict) else None
    return parse_dh_rows(block, n_joints, source, where, "delta", is_length)


def parse_dh_rows(
    block: Any, n_joints: int, source: str | Path, where: str, name: str,
    is_length: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """A table block ``{"a": [mm…], "d": [mm…], "alpha": [deg…], "theta": [deg…]}`` of n finite
    numbers each, as a (4, n) array in m and rad (with ``is_length`` (4, n), each entry in its
    own unit: a Hayati β in the ``d`` row is in degrees).

    Raises:
        InputError: naming ``where`` if the block has another shape or a value is not finite.
    """
    expected = f"{name!r} with lists a, d (mm), alpha, theta (deg) of {n_joints} numbers"
    if not isinstance(block, dict) or any(
        not isinstance(block.get(key), list) or len(block[key]) != n_joints
        or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in block[key])
        for key in DH_KEYS
    ):
        raise InputError(f"no valid {name!r}", expected, source=source, where=where)
    try:
        display = {key: [float(v) for v in block[key]] for key in DH_KEYS}
    except OverflowError:
        display = {key: [math.inf] for key in DH_KEYS}
    if not all(math.isfinite(v) for values in display.values() for v in values):
        raise InputError(f"a non-finite value in {name!r}", "finite numbers", source=source,
                         where=where)
    return dh_rows_from_display(display, is_length)


def load_truth_delta(path: str | Path, n_joints: int, is_length: ArrayLike | None = None
                     ) -> NDArray[np.float64]:
    """The true table errors of a truth file, shape (4, n), m and rad (``is_length`` as in
    :func:`parse_dh_rows`).

    Raises:
        InputError: if the file is not JSON or has no valid ``delta``.
    """
    return parse_delta(read_json(path, "a truth JSON file"), n_joints, path,
                       is_length=is_length)


def load_truth_attachment(path: str | Path) -> NDArray[np.float64]:
    """The true measured point in the flange frame of a truth file, shape (3,), m; the flange
    centre when the file does not say (written before twin simulated attachments).

    Raises:
        InputError: if the file is not JSON or ``attachment_mm`` is not three numbers.
    """
    truth = Table(read_json(path, "a truth JSON file"), path)
    return mm_to_m(truth.vector("attachment_mm", 3, default=[0.0, 0.0, 0.0],
                                expected="three numbers in mm"))
