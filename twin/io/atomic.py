"""Atomic, durable writes: a failure leaves either the old file or the new one, never half.

Every file is created with the mode the process umask gives (0644 under the usual 022), like
any other tool: the temporary file's private 0600 is not carried over.

A temporary file is named ``.<name>.<pid>-<random>.tmp`` after the file it becomes and the
process writing it. A process killed before its rename (SIGKILL, a power cut) leaves it behind;
the next write of the same file, and a folder command that takes the folder's lock
(:mod:`twin.io.lock`), remove those whose process is gone.
"""

from __future__ import annotations

import contextlib
import os
import re
import tempfile
from collections.abc import Iterator
from pathlib import Path

from twin.io.paths import check_output, os_error

WRITE_EXPECTED = "a file that can be written (a writable folder with free space)"
_TEMPORARY = re.compile(r"\.(?P<name>.+)\.(?P<pid>[0-9]+)-[a-z0-9_]+\.tmp")
"""The name of a temporary file of :func:`temporary_beside`."""


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
        remove_stale_temporaries(path.parent, path.name)
        fd, temporary = tempfile.mkstemp(prefix=f".{path.name}.{os.getpid()}-", suffix=".tmp",
                                         dir=path.parent)
        os.close(fd)
    except OSError as exc:
        raise os_error(path, "creating it", exc, WRITE_EXPECTED) from None
    return Path(temporary)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except PermissionError:  # another user's process
        return True
    except (ProcessLookupError, OverflowError):  # gone, or never a pid
        return False
    return True


def remove_stale_temporaries(folder: str | Path, name: str | None = None) -> list[Path]:
    """Remove the temporary files in ``folder`` (of the file ``name`` only, if given) whose
    writing process is gone; a live process's are left alone.

    Returns:
        The files removed.
    """
    removed = []
    with contextlib.suppress(FileNotFoundError, NotADirectoryError):
        for entry in os.scandir(folder):
            match = _TEMPORARY.fullmatch(entry.name)
            if match is None or (name is not None and match["name"] != name) \
                    or _alive(int(match["pid"])) or not entry.is_file(follow_symlinks=False):
                continue
            with contextlib.suppress(FileNotFoundError):
                os.unlink(entry.path)
                removed.append(Path(entry.path))
    return removed


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
