"""How the benchmarks time a run: the median wall time of repeated runs (one helper for every
script in bench/; its name starts with ``_`` because it is not a benchmark itself)."""

from __future__ import annotations

import argparse
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


def tiny_run(description: str | None) -> bool:
    """Parse a script's one flag, ``--tiny``: every part runs at a smoke size (CI runs each
    script so, tests/test_bench_smoke.py) and none of its figures means anything."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--tiny", action="store_true",
                        help="smoke size: every part runs, no figure means anything")
    return bool(parser.parse_args().tiny)
