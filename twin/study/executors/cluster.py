"""A Dask distributed cluster: a scheduler at an address, or a LocalCluster on 127.0.0.1.

Dask is imported here only (optional extra ``cluster``). A worker that dies has its tasks
rescheduled by the Dask scheduler (up to ``distributed.scheduler.allowed-failures`` times, 3 by
default); a task that fails with an exception is not retried, since trials are deterministic and
the same error would come back. The functions and work items are sent pickled, so a remote
cluster's workers need the same `twin` installed.
"""

from __future__ import annotations

import importlib
import logging
import socket
import tempfile
from collections.abc import Callable, Generator, Sequence
from typing import Any
from urllib.parse import urlsplit

from twin.errors import InputError, TwinError

CONNECT_TIMEOUT = "20s"
TRIAL_MODULE = "twin.study.trial"
SCHEMES = ("tcp", "tls", "ws", "wss")
"""Dask comm protocols a remote scheduler may listen on."""
PROBE_TIMEOUT_S = 5.0
"""How long :func:`reach_scheduler` waits for the scheduler's port to answer, s."""


def reach_scheduler(address: str, timeout_s: float = PROBE_TIMEOUT_S) -> None:
    """Check that ``address`` is a scheduler URL and that something listens there, before a
    study creates its folder (a TCP connection; Dask itself then says if it is a scheduler).

    Raises:
        InputError: if the address is not ``SCHEME://HOST:PORT`` or nothing answers there.
    """
    expected = "the address of a running dask scheduler, tcp://HOST:PORT"
    parts = urlsplit(address if "://" in address else f"tcp://{address}")
    try:
        port = parts.port
    except ValueError:
        port = None
    if parts.scheme not in SCHEMES or not parts.hostname or port is None \
            or parts.path not in ("", "/") or parts.query:
        raise InputError(f"{address!r}", expected, source="--scheduler")
    try:
        socket.create_connection((parts.hostname, port), timeout=timeout_s).close()
    except OSError as exc:
        reason = exc.strerror or exc.__class__.__name__
        raise InputError(f"no scheduler reachable at {address} ({reason})", expected,
                         source="--scheduler") from None


class DaskCluster:
    """Runs batches as Dask tasks.

    Args:
        scheduler: Address of a running scheduler, e.g. ``tcp://10.0.0.5:8786``; None starts a
            LocalCluster bound to 127.0.0.1.
        workers: Worker processes of the LocalCluster (one thread each); ignored with
            ``scheduler``.
    """

    def __init__(self, scheduler: str | None = None, workers: int | None = None) -> None:
        # Without the extra this raises the ImportError the CLI turns into the extra to
        # install, before a study writes anything.
        importlib.import_module("dask.distributed")
        self.scheduler = scheduler
        self._n_local = workers
        self.client: Any = None
        self._cluster: Any = None
        self._scratch: tempfile.TemporaryDirectory[str] | None = None

    def __enter__(self) -> DaskCluster:
        from dask.distributed import Client, LocalCluster

        if self.scheduler:
            try:
                self.client = Client(self.scheduler, timeout=CONNECT_TIMEOUT)
            except (OSError, TimeoutError, ValueError) as exc:
                raise InputError(f"no scheduler reachable at {self.scheduler} ({exc})",
                                 "the address of a running dask scheduler, tcp://HOST:PORT",
                                 source="--scheduler") from None
        else:
            import dask

            # The scheduler's and the workers' scratch folders in one of the study's own,
            # removed when it stops: Dask's default, dask-scratch-space in the temporary
            # folder, stays behind after every run (and a killed worker's folder in it).
            self._scratch = tempfile.TemporaryDirectory(prefix="twin-dask-")
            with dask.config.set({"temporary-directory": self._scratch.name}):
                self._cluster = LocalCluster(
                    n_workers=self._n_local, threads_per_worker=1, processes=True,
                    host="127.0.0.1", dashboard_address="127.0.0.1:0",
                    silence_logs=logging.ERROR,
                )
            self.client = Client(self._cluster)
        try:
            # Import the trial code on every worker now: a worker without twin fails here, with
            # a clear message, and the first batches do not pay for the imports.
            self.client.run(importlib.import_module, TRIAL_MODULE)
        except ImportError as exc:
            self.__exit__()
            raise InputError(f"dask workers that cannot import {TRIAL_MODULE} ({exc})",
                             "workers with the same twin installed as here",
                             source="--scheduler") from None
        return self

    def __exit__(self, *exc: object) -> None:
        if self.client is not None:
            self.client.close()
        if self._cluster is not None:
            self._cluster.close()
        if self._scratch is not None:
            self._scratch.cleanup()
        self.client = self._cluster = self._scratch = None

    @property
    def workers(self) -> int:
        """Threads across the cluster's workers."""
        info = self.client.scheduler_info()["workers"]
        return max(1, sum(int(w.get("nthreads", 1)) for w in info.values()))

    @property
    def forks(self) -> bool:
        """False: Dask's workers are processes of their own, which load what they run."""
        return False

    def run(self, function: Callable[[Any], Any], batches: Sequence[Any]
            ) -> Generator[Any, None, None]:
        """Yield ``function(batch)`` for every batch as its task finishes."""
        from dask.distributed import as_completed
        from distributed.scheduler import KilledWorker

        futures = [self.client.submit(function, batch, pure=False) for batch in batches]
        try:
            for future in as_completed(futures):
                try:
                    result = future.result()
                except KilledWorker as exc:
                    raise TwinError(f"a batch killed its worker every time it ran ({exc})"
                                    ) from None
                future.release()
                yield result
        finally:
            self.client.cancel(futures)
