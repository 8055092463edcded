"""One journal: a file of whole lines, each append durable before it returns, and the repair
of a line torn by a crash.

What `twin` records while it runs goes into journals: a capture's measurements, a study's
results and trial details. Every one follows the same rules:

- :meth:`Journal.append` writes its text with one ``write`` on an ``O_APPEND`` descriptor and
  ``fsync``-s it before returning: a kill (even SIGKILL) leaves it whole or absent; only a
  power cut can leave part of it.
- A last line without its LF is a torn line. :meth:`Journal.read` returns it apart from the
  whole lines and changes nothing; :meth:`Journal.recover` cuts it off the file in place, so
  the whole lines before it are never rewritten.
- A repair that drops more than a torn tail (a study's unfinished trials) replaces the file
  with :meth:`Journal.rewrite`, atomically (:mod:`twin.io.atomic`).

Check that a journal is of the right kind (its header, its rows) before recovering it: a
file that is not a journal must not lose its last line to a repair.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import NamedTuple

from twin.errors import TwinError
from twin.io.atomic import WRITE_EXPECTED, fsync_directory, write_atomic
from twin.io.paths import decode_text, os_error, read_bytes


class JournalText(NamedTuple):
    """A journal as read: its whole lines, and a torn last line apart."""

    whole: str
    """Every line that ends with its LF, header included, as text."""
    torn: bytes
    """A last line without its LF, as the bytes found (b"" if none)."""


def split_torn(raw: bytes) -> tuple[bytes, bytes]:
    """``(whole lines, torn last line)`` of a journal's bytes."""
    keep = raw.rfind(b"\n") + 1
    return raw[:keep], raw[keep:]


class Journal:
    """A file of whole lines appended durably (see the module's rules).

    Args:
        path: The file.
        what: What the file is, for messages ("a capture measurement CSV (pose, q1..q6,
            length)").
        header: Its first line, with its LF, or "" for none.
    """

    def __init__(self, path: str | Path, what: str, header: str = "") -> None:
        if header and not header.endswith("\n"):
            raise ValueError(f"header: {header!r}, expected a line ending with LF")
        self.path = Path(path)
        self.what = what
        self.header = header

    def read(self, *, as_input: bool = False) -> JournalText:
        """The journal's whole lines and its torn last line; changes nothing.

        Args:
            as_input: The journal of another run, read as an input (protected from being
                overwritten, size-limited) rather than as this run's own file.

        Raises:
            InputError: if the file is missing, not a regular file, or not text.
        """
        raw = read_bytes(self.path, self.what, journal=not as_input)
        whole, torn = split_torn(raw)
        return JournalText(decode_text(whole, self.path, self.what), torn)

    def recover(self) -> tuple[str, str | None]:
        """Start the journal with its header if it is missing or blank, and cut a torn last
        line off it.

        Returns:
            ``(whole, note)``: the whole lines as text, and a note naming what was dropped
            (None if nothing was).

        Raises:
            InputError: if the file cannot be read, repaired or created.
        """
        if not self.path.exists():
            self.rewrite("")
            return self.header, None
        raw = read_bytes(self.path, self.what, journal=True)
        if not raw.strip():
            self.rewrite("")
            return self.header, None
        whole, torn = split_torn(raw)
        if not torn:
            return decode_text(whole, self.path, self.what), None
        note = f"{self.path}: dropped a partial last line {torn!r} left by an interrupted write"
        if not whole:
            self.rewrite("")
            return self.header, note
        try:
            with open(self.path, "r+b") as handle:
                handle.truncate(len(whole))
                handle.flush()
                os.fsync(handle.fileno())
        except OSError as exc:
            raise os_error(self.path, "truncating its partial last line", exc,
                           WRITE_EXPECTED) from None
        return decode_text(whole, self.path, self.what), note

    def append(self, text: str) -> None:
        """Append whole lines and make them durable before returning.

        A journal with a header must exist (:meth:`recover` or :meth:`rewrite` first); one
        without is created.

        Raises:
            InputError: if the file cannot be written.
            TwinError: if the disk took only part of the text (a torn line is left, which
                :meth:`recover` drops).
        """
        if not text.endswith("\n"):
            raise ValueError("text: expected whole lines, ending with LF")
        data = text.encode("utf-8")
        created = not self.path.exists()
        try:
            # The mode is that of open(2) under the umask, like every file twin writes.
            fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_CLOEXEC, 0o666)
            try:
                written = os.write(fd, data)
                if written != len(data):
                    raise TwinError(f"{self.path}: wrote {written} of {len(data)} bytes "
                                    "(disk full?)")
                os.fsync(fd)
            finally:
                os.close(fd)
            if created:
                fsync_directory(self.path.parent)
        except OSError as exc:
            raise os_error(self.path, "appending to it", exc, WRITE_EXPECTED) from None

    def rewrite(self, body: str) -> None:
        """Replace the journal atomically with its header and ``body`` (whole lines)."""
        write_atomic(self.path, self.header + body)
