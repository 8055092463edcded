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
SIGTERM that stops it and kept the command from exiting. A stop that reaches this process while
it is inside concurrent.futures is acted on as it leaves (:class:`_StopsDeferred`).

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
import threading
import warnings
from collections.abc import Callable, Generator, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from queue import SimpleQueue
from types import FrameType
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
    # Started with both blocked (_stops_blocked): what arrived since is taken now, as set above.
    signal.pthread_sigmask(signal.SIG_UNBLOCK, STOPS)
    if not pinned:
        from threadpoolctl import threadpool_limits

        threadpool_limits(limits=1)


@contextmanager
def _stops_blocked() -> Iterator[None]:
    """SIGINT and SIGTERM blocked (held, not lost) in this thread, and so in the workers it
    starts, until the block ends; the command takes what arrived then."""
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, STOPS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


class _StopsDeferred:
    """This process's own stop handlers, deferred while it is inside concurrent.futures.

    The command's handlers raise (:class:`KeyboardInterrupt`, and SIGTERM as ``Terminated``)
    wherever the main thread is. Raised inside concurrent.futures — in ``wait()``, which takes
    every waiting future's lock in turn — the exception left a future's lock held, and the
    pool's shutdown then waited for ever for its manager thread, which waited for that lock
    (a study under SIGTERM hung in CI; raised at a random moment, 19 runs in 40 hung). While
    the run holds these handlers a stop that arrives :meth:`inside` is noted and handed to the
    handler it replaced when the block ends; elsewhere it goes to that handler at once, so the
    one left installed by a stop during :meth:`installed`'s restore behaves as the original.
    """

    def __init__(self) -> None:
        self._replaced: dict[int, Any] = {}
        self._inside = False
        self._noted: int | None = None

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        if self._inside:
            self._noted = self._noted or signum
            return
        handler = self._replaced[signum]
        if callable(handler):
            handler(signum, frame)
        elif handler == signal.SIG_DFL:
            signal.signal(signum, signal.SIG_DFL)
            signal.raise_signal(signum)

    @contextmanager
    def installed(self) -> Iterator[None]:
        """These handlers in place of the process's for the block (in the main thread only,
        the one thread where Python runs signal handlers)."""
        if threading.current_thread() is not threading.main_thread():
            yield
            return
        try:
            for stop in STOPS:
                if signal.getsignal(stop) is not None:  # None: a handler set outside Python
                    self._replaced[stop] = signal.signal(stop, self._handle)
            yield
        finally:
            for signum, handler in self._replaced.items():
                signal.signal(signum, handler)

    @contextmanager
    def inside(self) -> Iterator[None]:
        """A stop that arrives in the block is acted on when it ends."""
        self._inside = True
        try:
            yield
        finally:
            self._inside = False
            noted, self._noted = self._noted, None
            if noted is not None:
                self._handle(noted, None)


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

    def run(self, function: Callable[[Any], Any], batches: Sequence[Any]
            ) -> Generator[Any, None, None]:
        """Yield ``function(batch)`` for every batch as it finishes; rerun a dead worker's.
        Closing the generator stops the workers."""
        pending = dict(enumerate(batches))
        fruitless = 0
        stops = _StopsDeferred()
        with stops.installed():
            while pending:
                finished_any = yield from self._run_pool(function, pending, stops)
                if pending:
                    warnings.warn(f"a worker process died; running its {len(pending)} "
                                  "unfinished batches again on fresh processes", RuntimeWarning,
                                  stacklevel=2)
                fruitless = 0 if finished_any else fruitless + 1
                if pending and fruitless > MAX_FRUITLESS_RESTARTS:
                    raise TwinError(f"worker processes died {fruitless} times in a row without "
                                    f"finishing a batch; {len(pending)} batches not run")

    def _run_pool(self, function: Callable[[Any], Any], pending: dict[int, Any],
                  stops: _StopsDeferred) -> Generator[Any, None, bool]:
        """Run the ``pending`` batches (by index) in one pool until each has finished or the
        pool breaks, removing each batch as its result is yielded; whether any finished.

        Every call into concurrent.futures is made :meth:`_StopsDeferred.inside`; the wait for
        the next result is a queue's, which a stop interrupts cleanly."""
        finished: SimpleQueue[Future[Any]] = SimpleQueue()
        futures: dict[Future[Any], int] = {}
        with stops.inside():
            pool = ProcessPoolExecutor(max_workers=min(self._workers, len(pending)),
                                       mp_context=START, initializer=_start_worker,
                                       initargs=(self.forks and self._limits is not None,))
        finished_any = False
        try:
            with stops.inside(), _stops_blocked():  # the first submit starts every worker
                for index, batch in pending.items():
                    future = pool.submit(function, batch)
                    futures[future] = index
                    future.add_done_callback(finished.put)
            for _ in futures:
                future = finished.get()
                with stops.inside():
                    if isinstance(future.exception(), BrokenProcessPool):
                        break
                    result = future.result()
                del pending[futures[future]]
                finished_any = True
                yield result
        finally:
            with stops.inside():
                if pending:
                    _terminate(pool)
                pool.shutdown(wait=True, cancel_futures=True)
        return finished_any
