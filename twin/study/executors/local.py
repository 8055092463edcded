"""Local worker processes (one per core by default), with a killed worker's batches rerun.

Every worker runs its BLAS and OpenMP on one thread (through threadpoolctl, the library that
sets the thread count of the BLAS a numpy is linked to): the workers already take every core,
and a BLAS that starts a thread per core in each of them burns CPU fighting over the cores (a
trial cost 60 % more CPU unpinned, 2 workers no faster than one). On Linux workers are forked
(:data:`START`), so they start at once with what this process has imported; elsewhere they
start as the platform starts them (spawned on macOS, where the system's libraries, Accelerate
among them, are not safe to fork). While the executor is entered this process runs its BLAS on
one thread too — it runs a run's first trial (:func:`twin.study.runner.run_trials`) — and
forked workers inherit that; a spawned worker pins its own (:func:`_start_worker`). Pinning
again in a forked worker cost 0.17 s of CPU over its first ten trials, measured. They start with
SIGINT and SIGTERM blocked, until they have set their own handlers (:func:`_start_worker`): a
worker forked with the command's handlers, and stopped before it set its own, swallowed the
SIGTERM that stops it and kept the command from exiting.

A worker that dies breaks a :class:`~concurrent.futures.ProcessPoolExecutor` for every batch
still in it; the batches that had not finished are submitted again to a fresh pool. A pool that
breaks :data:`MAX_FRUITLESS_RESTARTS` times in a row without finishing any batch means a batch
kills its worker every time, and the run stops with :class:`~twin.errors.TwinError`.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import sys
import warnings
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from typing import Any

from twin.errors import TwinError

MAX_FRUITLESS_RESTARTS = 3
STOPS = frozenset({signal.SIGINT, signal.SIGTERM})
"""The signals that stop a run; held while workers start."""
START = multiprocessing.get_context("fork" if sys.platform.startswith("linux") else None)
"""How workers start: forked on Linux (named: Python 3.14 makes forkserver the default there),
the platform's default elsewhere."""


def _start_worker(pinned: bool) -> None:
    """Ignore Ctrl-C (it reaches the whole process group; the parent alone handles it and stops
    the pool), die at once on SIGTERM, and run BLAS and OpenMP on one thread for the worker's
    life (unless ``pinned``: forked from a process that did).

    A forked worker inherits the command's SIGTERM handler, which raises to stop the command
    as Ctrl-C does; in a worker that printed a traceback per worker when a supervisor stopped
    the whole process group, and a worker interrupted while reading its next batch could block
    the parent's shutdown for ever. The default action ends it silently: the parent alone
    handles SIGTERM, and stops (terminates) what is left of the pool."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    # Started with both blocked (_stops_held): what arrived since is taken now, as set above.
    signal.pthread_sigmask(signal.SIG_UNBLOCK, STOPS)
    if not pinned:
        from threadpoolctl import threadpool_limits

        threadpool_limits(limits=1)


@contextmanager
def _stops_held() -> Iterator[None]:
    """SIGINT and SIGTERM held (blocked, not lost) in this thread, and so in the workers it
    starts, until the block ends; the command takes what arrived then."""
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, STOPS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def _terminate(pool: ProcessPoolExecutor) -> None:
    # Python 3.11 has no public way to stop busy workers (3.14 adds terminate_workers()).
    for process in list((getattr(pool, "_processes", None) or {}).values()):
        process.terminate()


class LocalProcesses:
    """Runs batches in local worker processes.

    Args:
        workers: Number of processes; ``os.cpu_count()`` by default.
    """

    def __init__(self, workers: int | None = None) -> None:
        self._workers = workers or os.cpu_count() or 1
        self._limits: Any = None

    @property
    def workers(self) -> int:
        """Number of worker processes."""
        return self._workers

    @property
    def forks(self) -> bool:
        """Whether the workers are forked from this process (on Linux: :data:`START`)."""
        return START.get_start_method() == "fork"

    def __enter__(self) -> LocalProcesses:
        from threadpoolctl import threadpool_limits

        self._limits = threadpool_limits(limits=1)
        return self

    def __exit__(self, *exc: object) -> None:
        if self._limits is not None:
            self._limits.restore_original_limits()
            self._limits = None

    def run(self, function: Callable[[Any], Any], batches: Sequence[Any]) -> Iterator[Any]:
        """Yield ``function(batch)`` for every batch as it finishes; rerun a dead worker's."""
        pending = dict(enumerate(batches))
        fruitless = 0
        while pending:
            pool = ProcessPoolExecutor(max_workers=min(self._workers, len(pending)),
                                       mp_context=START,
                                       initializer=_start_worker,
                                       initargs=(self.forks and self._limits is not None,))
            finished_any = False
            clean = False
            try:
                with _stops_held():  # the first submit starts every worker
                    futures: dict[Future[Any], int] = {
                        pool.submit(function, batch): index for index, batch in pending.items()
                    }
                waiting = set(futures)
                while waiting:
                    done, waiting = wait(waiting, return_when=FIRST_COMPLETED)
                    broken = False
                    for future in done:
                        try:
                            result = future.result()
                        except BrokenProcessPool:
                            broken = True
                            continue
                        del pending[futures[future]]
                        finished_any = True
                        yield result
                    if broken:
                        break
                clean = not pending
            finally:
                if not clean:
                    _terminate(pool)
                pool.shutdown(wait=True, cancel_futures=True)
            if pending:
                warnings.warn(f"a worker process died; running its {len(pending)} unfinished "
                              "batches again on fresh processes", RuntimeWarning, stacklevel=2)
            fruitless = 0 if finished_any else fruitless + 1
            if pending and fruitless > MAX_FRUITLESS_RESTARTS:
                raise TwinError(f"worker processes died {fruitless} times in a row without "
                                f"finishing a batch; {len(pending)} batches not run")
