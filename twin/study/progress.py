"""A progress bar on stderr: trials done / total, elapsed time, estimated time left.

On a terminal the bar redraws in place; otherwise (a log file, CI) it prints a plain line at
most every few seconds and always the last one. The ETA extrapolates the rate of the trials
finished in this run after its first report, which pays what a run pays once (the imports, the
workers' start, the compiled kernels' loading; on a fresh install numba compiled them for 18 s
within the first trial, and the ETA then promised 1:28 for five trials that took a second);
trials resumed from an earlier run do not make it optimistic either.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TextIO

BAR_WIDTH = 28
CLEAR_TO_END = "\x1b[K"
"""ANSI: erase the rest of a redrawn line, which may be shorter than the one before."""
PLAIN_INTERVAL_S = 5.0
"""Shortest time between two plain (non-terminal) progress lines, s."""


def format_duration(seconds: float) -> str:
    """``m:ss`` or ``h:mm:ss``."""
    total = round(seconds)
    hours, rest = divmod(total, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


class Progress:
    """Counts finished trials and shows it.

    Args:
        total: Trials in the study.
        done: Trials already finished before this run (resumed).
        stream: Where to draw; stderr by default.
        label: What is counted.
    """

    def __init__(self, total: int, done: int = 0, stream: TextIO | None = None,
                 label: str = "trials") -> None:
        self.total = total
        self.done = done
        self.stream = stream if stream is not None else sys.stderr
        self.label = label
        self._start = time.monotonic()
        self._first: tuple[float, int] | None = None  # this run's first report: when, count
        self._last_plain = -float("inf")
        self._tty = self.stream.isatty()
        self._draw(force=True)

    def line(self) -> str:
        """The current state as one line of text."""
        now = time.monotonic()
        remaining = self.total - self.done
        if remaining == 0:
            eta = "done"
        elif self._first is not None and self.done > self._first[1]:
            since, counted = self._first
            eta = "ETA " + format_duration((now - since) / (self.done - counted) * remaining)
        else:
            eta = "ETA --:--"
        filled = BAR_WIDTH * self.done // max(self.total, 1)
        bar = "#" * filled + "." * (BAR_WIDTH - filled)
        return (f"[{bar}] {self.done}/{self.total} {self.label}, "
                f"{format_duration(now - self._start)} elapsed, {eta}")

    def advance(self, count: int = 1) -> None:
        """Count ``count`` more finished trials, reported at once (a worker's batch)."""
        self.done += count
        if self._first is None:
            self._first = (time.monotonic(), self.done)
        self._draw(force=self.done >= self.total)

    def _draw(self, force: bool) -> None:
        if self._tty:
            end = "\n" if self.done >= self.total else ""
            self.stream.write("\r" + self.line() + CLEAR_TO_END + end)
        else:
            now = time.monotonic()
            if not force and now - self._last_plain < PLAIN_INTERVAL_S:
                return
            self._last_plain = now
            self.stream.write(self.line() + "\n")
        self.stream.flush()

    def note(self, text: str) -> None:
        """Write ``text`` on a line of its own (above the bar on a terminal) and draw the bar
        again."""
        self.stream.write(("\r" + text + CLEAR_TO_END if self._tty else text) + "\n")
        self._draw(force=True)

    @contextmanager
    def note_after(self, seconds: float, text: str) -> Iterator[None]:
        """:meth:`note` ``text`` if the block is still running after ``seconds`` (from a timer
        thread, ended with the block: workers forked after it start from one thread)."""
        timer = threading.Timer(seconds, self.note, (text,))
        timer.start()
        try:
            yield
        finally:
            timer.cancel()
            timer.join()

    def close(self) -> None:
        """End the bar's line on a terminal if the run stopped early."""
        if self._tty and self.done < self.total:
            self.stream.write("\n")
            self.stream.flush()
