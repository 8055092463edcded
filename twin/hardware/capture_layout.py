"""The layout of a capture's measurement file, its journal (:mod:`twin.hardware.capture_session`):
its columns and header, and the refusal of another command's output that would replace one.

Apart from the capture session so that every command can check its outputs as it starts
(:func:`twin.cli.main`) without loading the hardware adapters the session imports (encoders,
robot sources, the RWS client, RAPID), which a command that captures nothing never needs:
`twin export` loaded 16 modules fewer, and took 1.099 s against 1.127 s (medians of 11
alternating runs).
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from twin.choices import MAX_JOINTS, MIN_JOINTS
from twin.dataset import REFERENCE, TIME
from twin.errors import InputError
from twin.io.measurements import approach_columns, joint_columns
from twin.io.paths import OutputFile
from twin.kinds.length import COLUMN as LENGTH_COLUMN

POSE_COLUMN = "pose"


def row_columns(n_joints: int) -> tuple[str, ...]:
    """The columns a resumed capture reads back: ``pose, q1..qN, length``."""
    return (POSE_COLUMN, *joint_columns(n_joints), LENGTH_COLUMN)


def capture_columns(n_joints: int) -> tuple[str, ...]:
    """Every column of a capture's measurement file (as
    :func:`twin.hardware.capture_session.format_row` writes them)."""
    return (*row_columns(n_joints), TIME, REFERENCE, *approach_columns(n_joints))


def capture_header(n_joints: int) -> str:
    """The first line of a capture's measurement file, with its LF."""
    return ",".join(capture_columns(n_joints)) + "\n"


def starts_as_journal(path: Path) -> bool:
    """Whether a regular file begins with the header of a capture's measurements."""
    if not path.is_file():
        return False
    headers = [capture_header(n).encode("utf-8") for n in range(MIN_JOINTS, MAX_JOINTS + 1)]
    try:
        with open(path, "rb") as handle:
            start = handle.read(max(map(len, headers)))
    except OSError:
        return False
    return any(start.startswith(header) for header in headers)


def refuse_capture_journal(values: Iterable[object]) -> None:
    """Refuse an output file that would replace a capture's measurements (only the capture
    appends to them).

    Raises:
        InputError: naming the file.
    """
    for value in values:
        if isinstance(value, OutputFile) and starts_as_journal(value):
            raise InputError("a capture's measurements", "an output that is not a "
                             "capture's journal (it would be replaced)", source=value)


__all__ = ["POSE_COLUMN", "capture_columns", "capture_header", "refuse_capture_journal",
           "row_columns", "starts_as_journal"]
