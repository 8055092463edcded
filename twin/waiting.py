"""Waiting in the main thread until the process is stopped, on whichever thread the stopping
signal lands.

A signal sent to a process goes to any of its threads that does not block it, and the threads
BLAS starts when numpy is imported (and a server's own) block none. Python runs the handler
(SIGTERM raising :class:`twin.cli.Terminated`, SIGINT :class:`KeyboardInterrupt`) in the main
thread only, the next time that thread runs Python: a main thread asleep in a wait that only
its own signal ends — a lock, a selector with nothing to do — never ran it, and the server
went on serving (both virtual devices did, SIGTERM sent to their second thread; the kernel
mostly hands it to the main thread, so it is rare: a CI teardown that waited 10 s for a virtual
encoder to stop is the likely case). A main thread that waits for its stop (a virtual device,
`--rerun-serve`'s web viewer) therefore wakes every :data:`WAKE_S` to let a pending handler
run. A foundation: the adapters that serve (hardware, viz) share it.
"""

from __future__ import annotations

import time
from typing import NoReturn

WAKE_S = 0.1
"""How often a waiting main thread wakes: the longest a stop waits for its handler."""


def serve_until_stopped() -> NoReturn:
    """Sleep in the main thread until a signal's handler raises."""
    while True:
        time.sleep(WAKE_S)


async def serve_until_stopped_async() -> NoReturn:
    """:func:`serve_until_stopped` inside an event loop: its tasks run meanwhile."""
    import asyncio  # the virtual encoder's alone: the controller serves from threads

    while True:
        await asyncio.sleep(WAKE_S)
