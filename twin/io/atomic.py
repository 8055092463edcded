"""Atomic, durable writes: a failure leaves either the old file or the new one, never half.

Every file is created with the mode the process umask gives (0644 under the usual 022), like
any other tool: the temporary file's private 0600 is not carried over.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

from twin.io.paths import check_output, os_error

WRITE_EXPECTED = "a file that can be written (a writable folder with free space)"


def write_atomic(path: str | Path, data: str | bytes) -> None:
    """Write ``data`` to ``path`` via a temporary file in the same folder, fsync, then rename.

    Raises:
        InputError: if ``path`` is not a valid output (:func:`twin.io.paths.check_output`: an
            input of the running command, a directory, a device…) or writing fails.
    """
    path = Path(path)
    payload = data.encode("utf-8") if isinstance(data, str) else data
    temporary = temporary_beside(path)
    with _removed_on_failure(temporary, path), open(temporary, "wb") as handle:
        handle.write(payload)
    commit(temporary, path)


def temporary_beside(path: str | Path) -> Path:
    """A new empty temporary file in the folder of ``path``, for a writer that opens files by
    name (Rerun's file sink); :func:`commit` then puts it in place.

    Raises:
        InputError: if ``path`` is not a valid output or its folder cannot take a file.
    """
    path = Path(path)
    check_output(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp",
                                         dir=path.parent)
        os.close(fd)
    except OSError as exc:
        raise os_error(path, "creating it", exc, WRITE_EXPECTED) from None
    return Path(temporary)


def commit(temporary: str | Path, path: str | Path) -> None:
    """Make ``temporary`` durable with the umask's mode and rename it to ``path``: a reader
    sees the old file or the whole new one, never half.

    Raises:
        InputError: if that fails; the temporary file is removed.
    """
    temporary, path = Path(temporary), Path(path)
    with _removed_on_failure(temporary, path):
        fd = os.open(temporary, os.O_RDONLY | os.O_CLOEXEC)
        try:
            os.fchmod(fd, file_mode())
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(temporary, path)
        fsync_directory(path.parent)


@contextlib.contextmanager
def _removed_on_failure(temporary: Path, path: Path) -> Iterator[None]:
    """Remove ``temporary`` if the block fails (Ctrl-C too); an ``OSError`` becomes the
    one-line error of ``path``."""
    try:
        yield
    except OSError as exc:
        temporary.unlink(missing_ok=True)
        raise os_error(path, "writing it", exc, WRITE_EXPECTED) from None
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise


def file_mode() -> int:
    """The mode of a new file under the process umask (0o644 under 022)."""
    return 0o666 & ~_umask()


def _umask() -> int:
    # Linux reports the umask in /proc; setting it to read it back is racy with other threads
    # that create files, so that is only the fallback.
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    umask = os.umask(0o022)
    os.umask(umask)
    return umask


def fsync_directory(folder: str | Path) -> None:
    """Make a rename or a new file in ``folder`` durable."""
    fd = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
