"""Where trials run: local processes, or a Dask cluster (optional extra ``cluster``).

Every executor has one method, ``run(function, batches)``, which calls ``function(batch)`` for
each batch somewhere and yields the results as they finish, in any order. A batch whose worker
dies is run again, so every batch's result is yielded exactly once. Executors are context
managers: entering starts the workers, leaving stops them. Each is registered in
:data:`EXECUTORS` and imported when asked for (Dask only then).
"""

from __future__ import annotations

from collections.abc import Callable, Generator, Sequence
from math import ceil
from typing import Any, Protocol, TypeVar

from twin.distribution import Lazy, Registry

Item = TypeVar("Item")

TASKS_PER_WORKER = 4
"""Batches per worker: enough to balance the load, few enough that scheduling stays cheap."""
MAX_BATCH = 10
"""Largest batch, so that a killed worker or an interrupt loses little finished work."""


class Executor(Protocol):
    """Runs batches of work and yields each batch's result once, as it finishes."""

    @property
    def workers(self) -> int:
        """Number of parallel workers (for sizing batches)."""
        ...

    @property
    def forks(self) -> bool:
        """Whether the workers are forked from this process (and inherit what it loaded)."""
        ...

    def run(self, function: Callable[[Any], Any], batches: Sequence[Any]
            ) -> Generator[Any, None, None]:
        """Yield ``function(batch)`` for every batch, as each finishes; closing the generator
        stops the batches still running."""
        ...

    def __enter__(self) -> Executor: ...

    def __exit__(self, *exc: object) -> None: ...


EXECUTORS: Registry[Callable[..., Executor]] = Registry("executor", {
    "local": Lazy("twin.study.executors.local:LocalProcesses"),
    "cluster": Lazy("twin.study.executors.cluster:DaskCluster"),
})
"""Every executor, by name: ``local(workers=None)`` processes on this machine (one per core),
``cluster(scheduler=None, workers=None)`` Dask, at a scheduler or on a LocalCluster."""


def open_executor(scheduler: str | None = None, workers: int | None = None) -> Executor:
    """Where trials run: the Dask ``cluster`` at ``scheduler`` or of ``workers`` local
    workers when either is given, else ``local`` processes, one per core."""
    if scheduler or workers:
        return EXECUTORS["cluster"](scheduler, workers)
    return EXECUTORS["local"]()


def make_batches(items: Sequence[Item], workers: int) -> list[tuple[Item, ...]]:
    """Split work items into about :data:`TASKS_PER_WORKER` batches per worker, in order."""
    size = max(1, min(MAX_BATCH, ceil(len(items) / (max(workers, 1) * TASKS_PER_WORKER))))
    return [tuple(items[i : i + size]) for i in range(0, len(items), size)]


__all__ = ["EXECUTORS", "Executor", "make_batches", "open_executor"]
