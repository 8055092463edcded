"""The journal: durable appends, and a torn last line dropped without touching whole ones."""

from __future__ import annotations

import os
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest

from twin.errors import InputError
from twin.io.journal import Journal

HEADER = "pose,length\n"


def test_read_splits_off_a_torn_line_and_changes_nothing(tmp_path: Path) -> None:
    """Reading returns the whole lines and the torn tail apart; the file keeps its bytes."""
    path = tmp_path / "rows.csv"
    raw = (HEADER + "1,500.0\n2,501").encode()
    path.write_bytes(raw)
    text = Journal(path, "a test journal", HEADER).read()
    assert text.whole == HEADER + "1,500.0\n" and text.torn == b"2,501"
    assert path.read_bytes() == raw


def test_recover_cuts_a_torn_line_in_place(tmp_path: Path) -> None:
    """A power cut's tail (here NUL bytes after a partial line) is cut off the same file:
    the whole lines before it are not rewritten, and the note names what was dropped."""
    path = tmp_path / "rows.csv"
    path.write_bytes((HEADER + "1,500.0\n2,5").encode() + b"\x00" * 8)
    inode = os.stat(path).st_ino
    whole, note = Journal(path, "a test journal", HEADER).recover()
    assert whole == HEADER + "1,500.0\n" and path.read_text() == whole
    assert os.stat(path).st_ino == inode
    assert note is not None and "2,5\\x00" in note and "partial last line" in note
    assert Journal(path, "a test journal", HEADER).recover() == (whole, None)


def test_recover_starts_a_missing_blank_or_wholly_torn_journal(tmp_path: Path) -> None:
    """Missing, blank, or holding only a torn header: the journal starts with its header."""
    journal = Journal(tmp_path / "rows.csv", "a test journal", HEADER)
    assert journal.recover() == (HEADER, None) and journal.path.read_text() == HEADER
    journal.path.write_text("\n \n")
    assert journal.recover() == (HEADER, None) and journal.path.read_text() == HEADER
    journal.path.write_text("pose,le")
    whole, note = journal.recover()
    assert whole == HEADER and note is not None and journal.path.read_text() == HEADER


def test_a_binary_journal_is_refused(tmp_path: Path) -> None:
    """A NUL byte among the whole lines is not a torn tail: the file is not a journal."""
    path = tmp_path / "rows.csv"
    path.write_bytes(HEADER.encode() + b"1,\x00\n")
    with pytest.raises(InputError, match="binary data"):
        Journal(path, "a test journal", HEADER).recover()


@pytest.mark.parametrize("mask", [0o022, 0o077])
def test_append_creates_a_headerless_journal_with_the_umask_mode(tmp_path: Path,
                                                                 mask: int) -> None:
    """A journal without a header is created by its first append, 0666 & ~umask."""
    old = os.umask(mask)
    try:
        journal = Journal(tmp_path / "details.jsonl", "a test journal")
        journal.append('{"trial": 0}\n')
        journal.append('{"trial": 1}\n')
    finally:
        os.umask(old)
    assert journal.path.read_text() == '{"trial": 0}\n{"trial": 1}\n'
    assert stat.S_IMODE(os.stat(journal.path).st_mode) == 0o666 & ~mask
    with pytest.raises(ValueError, match="whole lines"):
        journal.append("no end of line")


def test_a_killed_writer_leaves_only_whole_lines(tmp_path: Path) -> None:
    """SIGKILL in the middle of a stream of appends: every line in the file is whole (one
    write per append), and recovering drops nothing."""
    path = tmp_path / "rows.csv"
    Journal(path, "a test journal", HEADER).recover()
    code = ("import sys\nfrom twin.io.journal import Journal\n"
            f"journal = Journal({str(path)!r}, 'a test journal', {HEADER!r})\n"
            "print('ready', flush=True)\n"
            "for pose in range(1, 10**7):\n"
            "    journal.append(f'{pose},' + '5' * 200 + '\\n')\n")
    writer = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    assert writer.stdout is not None and writer.stdout.readline() == "ready\n"
    deadline = time.monotonic() + 30
    while path.stat().st_size < 20_000:
        assert time.monotonic() < deadline, "the writer appended too little"
        time.sleep(0.01)
    writer.send_signal(signal.SIGKILL)
    writer.wait()
    text = Journal(path, "a test journal", HEADER).read()
    assert text.torn == b""
    poses = [int(line.split(",")[0]) for line in text.whole.splitlines()[1:]]
    assert poses == list(range(1, len(poses) + 1)) and len(poses) > 50
