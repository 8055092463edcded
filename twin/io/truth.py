"""Ground-truth files (`truth.json`) written by the twin beside a simulated capture.

The D-H error block ``"delta"`` is the same in a truth file and in a calibration result
(`twin calibrate --json`); :func:`read_json` and :func:`parse_delta` read it for both.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from twin.errors import InputError
from twin.io.measurements import read_text
from twin.units import DH_KEYS, dh_rows_from_display


def read_json(path: str | Path, what: str) -> Any:
    """The parsed JSON document of a user file.

    Raises:
        InputError: if the file cannot be read or is not JSON.
    """
    try:
        return json.loads(read_text(path, what))
    except json.JSONDecodeError as exc:
        raise InputError(f"invalid JSON ({exc.msg} at line {exc.lineno})", what,
                         source=path) from None


def parse_delta(
    document: Any, n_joints: int, source: str | Path, where: str = "delta"
) -> NDArray[np.float64]:
    """The D-H errors under ``document["delta"]``, shape (4, n), m and rad.

    Args:
        document: A parsed JSON document (truth or result).
        n_joints: Number of joints n the robot has.
        source: The file, for the error message.
        where: Where ``document`` sits in the file, for the error message.

    Raises:
        InputError: if there is no ``delta`` with lists a, d (mm), alpha, theta (deg) of n numbers.
    """
    delta = document.get("delta") if isinstance(document, dict) else None
    if not isinstance(delta, dict) or any(
        not isinstance(delta.get(key), list) or len(delta[key]) != n_joints
        or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in delta[key])
        for key in DH_KEYS
    ):
        raise InputError(
            "no valid 'delta'", f"'delta' with lists a, d (mm), alpha, theta (deg) of {n_joints}",
            source=source, where=where,
        )
    rows = dh_rows_from_display(delta)
    if not np.all(np.isfinite(rows)):
        raise InputError("a non-finite value in 'delta'", "finite numbers", source=source,
                         where=where)
    return rows


def load_truth_delta(path: str | Path, n_joints: int) -> NDArray[np.float64]:
    """The true D-H errors of a truth file, shape (4, n), m and rad.

    Raises:
        InputError: if the file is not JSON or has no valid ``delta``.
    """
    return parse_delta(read_json(path, "a truth JSON file"), n_joints, path)
