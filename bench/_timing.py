"""How the benchmarks time a run: the median wall time of repeated runs (one helper for every
script in bench/; its name starts with ``_`` because it is not a benchmark itself)."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from typing import TypeVar

Result = TypeVar("Result")


def median_time(run: Callable[[], Result], repeats: int) -> tuple[float, Result]:
    """Median wall time of ``repeats`` runs of ``run``, s, and the last run's result."""
    if repeats < 1:
        raise ValueError(f"repeats: {repeats}, expected at least 1")
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        result = run()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result
