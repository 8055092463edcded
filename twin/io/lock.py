"""One writer per folder: the lock every folder command (`capture`, `simulate`, `study`,
`check`) holds while it writes there.

``DIR/.lock`` carries an exclusive ``flock``, which the kernel drops when the holder dies (even
by SIGKILL), and says who holds it (pid, host, start time, command) so that a second writer is
told in one line. The holder removes the file when it is done, also after a failure, and the
folders it created for it if they stayed empty: an early failure leaves nothing behind. A
``.lock`` left by a killed run is not held by anyone and is taken over by the next.

While it holds the lock, a command removes the temporary files a killed run left in the folder
(:func:`twin.io.atomic.remove_stale_temporaries`).
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import socket
import time
from collections.abc import Iterator
from pathlib import Path

from twin.errors import InputError
from twin.io.atomic import remove_stale_temporaries
from twin.io.paths import os_error
from twin.io.table import SHOWN_CHARS, shown

LOCK_NAME = ".lock"
ATTEMPTS = 10
"""Tries to take a lock whose file a finishing holder removes under us (a new file each time)."""
HOLDER_BYTES = 4096
"""Longest holder record read back."""


def _created_folders(folder: Path) -> list[Path]:
    """Create ``folder`` and its missing parents; returns those it created, deepest first."""
    missing = [folder, *folder.parents]
    missing = missing[:next((i for i, path in enumerate(missing) if path.exists()),
                            len(missing))]
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise os_error(folder, "creating it", exc, "a folder to write into") from None
    return missing


def _remove_if_empty(folders: list[Path]) -> None:
    for path in folders:
        with contextlib.suppress(OSError):  # not empty: something was written, keep it
            path.rmdir()


def _holder(fd: int) -> str:
    """Who holds the lock, as its file says."""
    try:
        record = json.loads(os.pread(fd, HOLDER_BYTES, 0).decode("utf-8"))
        started = time.strftime("%Y-%m-%d %H:%M:%S %Z",
                                time.localtime(float(record["started"])))
        command = str(record["command"])[:SHOWN_CHARS]
        return (f"{command}, pid {int(record['pid'])} on host {shown(str(record['host']))}, "
                f"started {started}")
    except (OSError, ValueError, KeyError, TypeError, OverflowError):
        return "a process that has not said which yet"


def _same_file(fd: int, path: Path) -> bool:
    """Whether ``path`` still names the file ``fd`` locked (a finishing holder removes it)."""
    try:
        on_disk = os.stat(path)
    except FileNotFoundError:
        return False
    held = os.fstat(fd)
    return (held.st_dev, held.st_ino) == (on_disk.st_dev, on_disk.st_ino)


def _acquire(folder: Path, command: str) -> int:
    path = folder / LOCK_NAME
    for _ in range(ATTEMPTS):
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        except OSError as exc:
            raise os_error(path, "creating it", exc, "a folder to write into") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _holder(fd)
            os.close(fd)
            raise InputError(f"another command writing this folder ({holder})", "one "
                             "command writing a folder at a time: wait for it to end, or "
                             "another --out folder", source=folder) from None
        if _same_file(fd, path):
            record = {"command": command, "pid": os.getpid(), "host": socket.gethostname(),
                      "started": time.time()}
            os.ftruncate(fd, 0)
            os.pwrite(fd, (json.dumps(record) + "\n").encode("utf-8"), 0)
            return fd
        os.close(fd)
    raise InputError(f"a lock {path} taken and released {ATTEMPTS} times in a row",
                     "one command writing a folder at a time", source=folder)


@contextlib.contextmanager
def folder_lock(folder: str | Path, command: str) -> Iterator[None]:
    """Hold ``folder``'s lock (creating the folder) for the block, or fail at once.

    Args:
        folder: The folder written.
        command: Who writes, for a second writer's message ("twin study").

    Raises:
        InputError: if another process holds the lock (naming it), or the folder cannot be
            created.
    """
    folder = Path(folder)
    created = _created_folders(folder)
    try:
        fd = _acquire(folder, command)
    except BaseException:
        _remove_if_empty(created)
        raise
    try:
        remove_stale_temporaries(folder)
        yield
    finally:
        # Removed while still held: a writer waiting on this file sees it gone and retries.
        (folder / LOCK_NAME).unlink(missing_ok=True)
        os.close(fd)
        _remove_if_empty(created)
