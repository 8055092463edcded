"""Ground-truth files (`truth.json`) written by the twin beside a simulated capture."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from twin.errors import InputError
from twin.io.measurements import read_text
from twin.units import DH_KEYS, dh_rows_from_display


def load_truth_delta(path: str | Path, n_joints: int) -> NDArray[np.float64]:
    """The true D-H errors of a truth file, shape (4, n), m and rad.

    Raises:
        InputError: if the file is not JSON or has no valid ``delta``.
    """
    try:
        document: Any = json.loads(read_text(path, "a truth JSON file"))
    except json.JSONDecodeError as exc:
        raise InputError(f"invalid JSON ({exc.msg} at line {exc.lineno})", "a truth JSON file",
                         source=path) from None
    delta = document.get("delta") if isinstance(document, dict) else None
    if not isinstance(delta, dict) or any(
        not isinstance(delta.get(key), list) or len(delta[key]) != n_joints
        or not all(isinstance(v, int | float) for v in delta[key])
        for key in DH_KEYS
    ):
        raise InputError(
            "no valid 'delta'", f"'delta' with lists a, d (mm), alpha, theta (deg) of {n_joints}",
            source=path, where="delta",
        )
    return dh_rows_from_display(delta)
