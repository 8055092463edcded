"""The frame flags of `twin compensate`: ``--tool`` and ``--wobj`` as ``[NAME=]X,Y,Z[,QW,QX,QY,QZ]``
(mm and a unit quaternion, scalar first, as ABB writes them), ``--tool0-in-flange``."""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING

from twin.errors import InputError

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from twin.io.rapid_filter import TargetFrames


RAPID_SUFFIXES = (".mod", ".modx", ".sys")
"""The file name endings of a RAPID module."""
EXPECTED = "X,Y,Z in mm, then optionally QW,QX,QY,QZ (a unit quaternion)"


def parse_pose_mm(text: str, flag: str, *, full: bool = False) -> NDArray[np.float64]:
    """A pose ``X,Y,Z[,QW,QX,QY,QZ]`` (mm, quaternion scalar first) as a 4×4 transform in m.

    Raises:
        InputError: naming the flag, for anything but 3 (or, unless ``full``, 7) finite
            numbers, or a quaternion that is not a unit one.
    """
    from twin.compensation.poses import pose_matrices
    from twin.units import mm_to_m

    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    counts = (7,) if full else (3, 7)
    if len(values) not in counts or not all(math.isfinite(v) for v in values):
        raise InputError(f"{text!r}", EXPECTED if not full else
                         "X,Y,Z,QW,QX,QY,QZ: mm and a unit quaternion", source=flag)
    quaternion = values[3:] if len(values) == 7 else [1.0, 0.0, 0.0, 0.0]
    try:
        return pose_matrices(mm_to_m(values[:3]), quaternion)[0]
    except ValueError as exc:
        raise InputError(f"{text!r} ({exc})", EXPECTED, source=flag) from None


def _named(values: list[str] | None, flag: str) -> dict[str | None, NDArray[np.float64]]:
    found: dict[str | None, NDArray[np.float64]] = {}
    for value in values or []:
        name, equals, pose = value.partition("=")
        key = name.strip() if equals else None
        if key in found:
            raise InputError(f"{flag} {key or '(unnamed)'} twice", "each tool or work object "
                             "once", source=flag)
        found[key] = parse_pose_mm(pose if equals else value, flag)
    return found


def parse_frames(args: argparse.Namespace) -> TargetFrames:
    """The tools and work objects the flags give, by name (None for the unnamed one)."""
    from twin.io.rapid_filter import TargetFrames

    return TargetFrames(_named(args.tool, "--tool"), _named(args.wobj, "--wobj"))
