"""Identified D-H errors read back from a calibration result (`twin calibrate --json`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from twin.errors import InputError, UnknownChoiceError
from twin.io.truth import parse_delta, read_json

RESULT_FILE = "a calibration result JSON file (twin calibrate --json)"


def load_result_delta(
    path: str | Path, n_joints: int, method: str | None = None
) -> NDArray[np.float64]:
    """The identified D-H errors of a result file, shape (4, n), m and rad.

    A file of one result has ``"delta"`` at the top; a file written with ``--method all`` has
    ``{"methods": {name: result}}`` and needs ``method`` to pick one.

    Args:
        path: The result JSON file.
        n_joints: Number of joints n of the robot.
        method: Name of the result to take from a multi-method file; must match the single
            result's ``"method"`` if given for a single-result file.

    Raises:
        InputError: if the file is not a result, or ``method`` is missing or unknown.
    """
    document = read_json(path, RESULT_FILE)
    if not isinstance(document, dict):
        raise InputError(f"a JSON {type(document).__name__}", "a JSON object", source=path)
    methods = document.get("methods")
    if isinstance(methods, dict):
        if method is None:
            raise InputError(
                "results of several methods (" + ", ".join(methods) + ")",
                "--method NAME to pick one", source=path,
            )
        if method not in methods:
            raise UnknownChoiceError("method", method, methods, source=str(path))
        return parse_delta(methods[method], n_joints, path, where=f"methods.{method}.delta")
    if method is not None and document.get("method") != method:
        raise UnknownChoiceError("method", method, [str(document.get("method"))],
                                 source=str(path))
    return parse_delta(document, n_joints, path)
