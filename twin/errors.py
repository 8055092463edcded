"""Exceptions. Everything `twin` raises on purpose derives from :class:`TwinError`.

A :class:`InputError` is a user mistake (a bad file, flag or value): the CLI prints its one-line
message and exits with code 2, without a traceback.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path


class TwinError(Exception):
    """Root of every error raised on purpose by `twin`."""


class InputError(TwinError):
    """A user mistake in a file, a flag or a value.

    Attributes:
        source: The file or flag the mistake is in, or None.
        where: Row, column, key or field inside the source, or None.
        found: What was found, already formatted for humans.
        expected: What was expected, formatted for humans.
    """

    def __init__(
        self,
        found: str,
        expected: str,
        *,
        source: str | Path | None = None,
        where: str | None = None,
    ) -> None:
        self.source = None if source is None else str(source)
        self.where = where
        self.found = found
        self.expected = expected
        parts = [p for p in (self.source, where) if p]
        prefix = ": ".join(parts) + ": " if parts else ""
        super().__init__(f"{prefix}found {found}, expected {expected}")

    def at(self, source: str | Path, where: str | None = None) -> InputError:
        """This mistake as made in ``source`` (the flag or file a value came from), unless it
        already names its source; ``where`` replaces the field it names, if given (``""``:
        none, as for a flag)."""
        if self.source is not None:
            return self
        return InputError(self.found, self.expected, source=source,
                          where=self.where if where is None else where or None)


class UnknownChoiceError(InputError):
    """A name that is not one of a fixed set of choices (method, protocol, format…)."""

    def __init__(self, kind: str, name: str, choices: Iterable[str], *, source: str | None = None):
        self.choices = tuple(choices)
        super().__init__(
            f"unknown {kind} {name!r}",
            "one of " + ", ".join(self.choices),
            source=source,
        )
