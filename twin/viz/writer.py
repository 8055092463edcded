"""Write archetypes and columns to a recording, optionally stamped with extra timelines.

A study logs many calibrations into one recording; each is stamped with, e.g., ``{"case": k}``.
Without extra timelines, per-run values (port, parameters, report) are static and series go on
their own timeline (``pose``, ``iteration``).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np
import rerun as rr
from numpy.typing import ArrayLike


class Writer:
    """A recording stream plus the extra sequence times stamped on everything written.

    Args:
        stream: The recording.
        times: Extra sequence timelines and their values, e.g. ``{"case": 3}``; None or empty
            for none.
    """

    def __init__(self, stream: rr.RecordingStream, times: Mapping[str, int] | None = None):
        self.stream = stream
        self.times = dict(times or {})

    def once(self, path: str, *archetypes: rr.AsComponents) -> None:
        """Values that hold for the whole run: static, or at the extra times if any."""
        if not self.times:
            self.stream.log(path, *archetypes, static=True)
            return
        for timeline, value in self.times.items():
            self.stream.set_time(timeline, sequence=value)
        self.stream.log(path, *archetypes)
        self.stream.reset_time()

    def series(
        self, path: str, timeline: str, sequence: ArrayLike, columns: Iterable[rr.ComponentColumn]
    ) -> None:
        """One row per element of ``sequence`` (ints) on ``timeline``, in one call."""
        sequence = np.asarray(sequence, dtype=np.int64)
        indexes = [rr.TimeColumn(timeline, sequence=sequence)]
        indexes += [
            rr.TimeColumn(name, sequence=np.full(sequence.shape, value, dtype=np.int64))
            for name, value in self.times.items()
        ]
        self.stream.send_columns(path, indexes=indexes, columns=columns)
