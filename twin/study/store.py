"""A study's folder: `results.csv` and `trials.jsonl` appended durably, `study.json` for resume.

Every finished trial is appended as one write of its JSON detail line (histories, residuals,
parameter errors) to `trials.jsonl`, then one write of its rows (one per method) to
`results.csv`, each followed by an fsync (both are journals, :mod:`twin.io.journal`).
`results.csv` is the record of what is finished: on reopening, a torn last line (the run was
killed mid-write) and any trial with fewer rows than methods are dropped, and detail lines of
trials not in the CSV are dropped, so every trial is counted exactly once whatever point a run
was killed at.

`study.json` holds the study's fingerprint: the parsed scenario document (less the number of
trials, which may grow between runs) and the methods. A run whose fingerprint differs is refused
with an :class:`~twin.errors.InputError` that names the first difference.
"""

from __future__ import annotations

import csv
import hashlib
import json
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

from twin.errors import InputError
from twin.io.atomic import write_atomic
from twin.io.journal import Journal
from twin.io.paths import os_error, read_json
from twin.study.rows import COLUMNS, HEADER, TrialRow, format_rows, parse_row

if TYPE_CHECKING:
    from twin.study.definition import StudyPlan

RESULTS = "results.csv"
DETAILS = "trials.jsonl"
MANIFEST = "study.json"

TrialKey = tuple[str, int]
"""(case label, trial index): a trial's identity in a study."""


class TrialOutcome(NamedTuple):
    """Everything one trial produced, as it is stored."""

    case: str
    """Label of the sweep point ("" without a sweep)."""
    trial: int
    """Trial index within the case, 0-based."""
    seed: int
    """Seed of the trial's draws (perturbation, poses, noise, split, methods)."""
    rows: tuple[TrialRow, ...]
    """One row per method."""
    detail: dict[str, Any]
    """JSON-ready per-method detail: histories, residuals, parameter errors."""

    @property
    def key(self) -> TrialKey:
        """The trial's identity."""
        return (self.case, self.trial)


def fingerprint(document: Mapping[str, Any], methods: Sequence[str]) -> str:
    """SHA-256 of the study's defining content (methods in any order), hex."""
    text = json.dumps({"scenario": document, "methods": sorted(methods)}, sort_keys=True)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def first_difference(old: Any, new: Any, path: str = "") -> str | None:
    """The first dotted key at which two JSON-like values differ, with both values."""
    if isinstance(old, dict) and isinstance(new, dict):
        for key in sorted(set(old) | set(new)):
            where = f"{path}.{key}" if path else str(key)
            if key not in old:
                return f"{where!r} added ({new[key]!r})"
            if key not in new:
                return f"{where!r} removed (was {old[key]!r})"
            found = first_difference(old[key], new[key], where)
            if found:
                return found
        return None
    if old != new:
        return f"{path or 'the document'!r} changed from {old!r} to {new!r}"
    return None


def parse_results(text: str, source: str | Path) -> dict[TrialKey, list[TrialRow]]:
    """The rows of a `results.csv` text of whole lines (a torn last line split off by
    :meth:`~twin.io.journal.Journal.read`), grouped by trial.

    Raises:
        InputError: for another header or a line with the wrong number of fields.
    """
    lines = text.splitlines(keepends=True)
    if not lines or lines[0].strip() != HEADER.strip():
        raise InputError(f"{RESULTS} with another header", f"the header {HEADER.strip()}",
                         source=source)
    rows: dict[TrialKey, list[TrialRow]] = {}
    try:
        records = list(csv.reader(lines[1:]))
    except csv.Error as exc:
        raise InputError(f"a line that is not CSV ({exc})", "the rows `twin study` writes",
                         source=source) from None
    for number, values in enumerate(records, start=2):
        if len(values) != len(COLUMNS):
            raise InputError(f"{len(values)} fields", f"{len(COLUMNS)}", source=source,
                             where=f"line {number}")
        try:
            row = parse_row(values)
        except ValueError as exc:
            raise InputError(f"a value that is not a number ({exc})", "the rows `twin study` "
                             "writes", source=source, where=f"line {number}") from None
        rows.setdefault((row.case, row.trial), []).append(row)
    return rows


def read_results(folder: str | Path) -> dict[TrialKey, list[TrialRow]]:
    """The finished rows of another study's folder, grouped by trial, read only: a torn last
    line is left out and nothing is repaired or written.

    Raises:
        InputError: if the folder has no readable `results.csv`.
    """
    path = Path(folder) / RESULTS
    results = Journal(path, f"the {RESULTS} of an earlier `twin study` or `twin check` run")
    return parse_results(results.read(as_input=True).whole, path)


def _journal(path: Path, what: str, header: str = "") -> Journal:
    return Journal(path, f"{what} of an earlier `twin study` run, or a new --out folder",
                   header)


class StudyStore:
    """The files of one study folder.

    Args:
        folder: The study folder (created if missing).
        manifest: What defines the study: ``{"scenario": document, "methods": [...], ...}``;
            only ``scenario`` and ``methods`` enter the fingerprint.
        source: The scenario file, named in the message when a resumed study differs.
    """

    def __init__(self, folder: str | Path, manifest: Mapping[str, Any], source: str | Path):
        self.folder = Path(folder)
        self.methods = tuple(manifest["methods"])
        self.fingerprint = fingerprint(manifest["scenario"], self.methods)
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise os_error(self.folder, "creating it", exc, "a folder to write into") from None
        manifest_path = self.folder / MANIFEST
        if manifest_path.exists():
            self._check_same(manifest_path, manifest, source)
        else:
            write_atomic(manifest_path, json.dumps(
                {"fingerprint": self.fingerprint, **manifest}, indent=2, sort_keys=True) + "\n")
        self._results = _journal(self.results_path, f"the {RESULTS}", HEADER)
        self._details = _journal(self.details_path, f"the {DETAILS}")
        self._rows: dict[TrialKey, list[TrialRow]] = {}
        self._details_by_key: dict[TrialKey, dict[str, Any]] = {}
        self._repair()

    @property
    def results_path(self) -> Path:
        """`results.csv`."""
        return self.folder / RESULTS

    @property
    def details_path(self) -> Path:
        """`trials.jsonl`."""
        return self.folder / DETAILS

    def _check_same(self, path: Path, manifest: Mapping[str, Any], source: str | Path) -> None:
        stored = read_json(path, f"the {MANIFEST} of an earlier `twin study` run, or a new --out "
                           "folder", journal=True)
        if not isinstance(stored, dict):
            raise InputError(f"a JSON {type(stored).__name__}", f"the {MANIFEST} of an earlier "
                             "`twin study` run, or a new --out folder", source=path)
        if stored.get("fingerprint") == self.fingerprint:
            return
        old = {"scenario": stored.get("scenario"), "methods": sorted(stored.get("methods", []))}
        new = {"scenario": manifest["scenario"], "methods": sorted(self.methods)}
        change = first_difference(old, new) or "a different fingerprint"
        raise InputError(
            f"a study in {self.folder} made from another scenario or methods: {change}",
            "the same scenario and methods to resume it, or a new --out folder",
            source=source,
        )

    def _repair(self) -> None:
        """Load what is finished; drop a torn tail and incomplete trials from both files."""
        rows, csv_dirty = self._read_rows()
        complete = {key: group for key, group in rows.items()
                    if sorted(r.method for r in group) == sorted(self.methods)}
        details, details_dirty = self._read_details(set(complete))
        if csv_dirty or len(complete) != len(rows):
            self._results.rewrite(format_rows(r for group in complete.values() for r in group))
        if details_dirty:
            self._details.rewrite("".join(json.dumps(d, sort_keys=True) + "\n"
                                          for d in details.values()))
        self._rows, self._details_by_key = complete, details

    def _read_rows(self) -> tuple[dict[TrialKey, list[TrialRow]], bool]:
        if not self.results_path.exists():
            self._results.rewrite("")
            return {}, False
        text = self._results.read()
        return parse_results(text.whole, self.results_path), bool(text.torn)

    def _read_details(self, finished: set[TrialKey]) -> tuple[dict[TrialKey, dict[str, Any]], bool]:
        if not self.details_path.exists():
            return {}, False
        text = self._details.read()
        details: dict[TrialKey, dict[str, Any]] = {}
        dirty = bool(text.torn)
        for line in text.whole.splitlines():
            try:
                detail: Any = json.loads(line)
            except (json.JSONDecodeError, RecursionError):
                detail = None
            key = (detail.get("case"), detail.get("trial")) if isinstance(detail, dict) \
                else None
            if key is None or key not in finished or key in details:
                dirty = True
                continue
            details[key] = detail
        return details, dirty

    def finished(self) -> set[TrialKey]:
        """Keys of the trials already recorded."""
        return set(self._rows)

    def record(self, outcomes: Sequence[TrialOutcome]) -> list[TrialOutcome]:
        """Record finished trials durably, a batch at once (one write and fsync per file, not
        two per trial); trials already recorded, or twice in the batch, are ignored.

        Returns:
            The trials that were new, in order.
        """
        new: dict[TrialKey, TrialOutcome] = {}
        for outcome in outcomes:
            if outcome.key not in self._rows:
                new.setdefault(outcome.key, outcome)
        if not new:
            return []
        details = {key: {"case": outcome.case, "trial": outcome.trial, "seed": outcome.seed,
                         **outcome.detail} for key, outcome in new.items()}
        self._details.append("".join(json.dumps(detail, sort_keys=True) + "\n"
                                     for detail in details.values()))
        self._results.append(format_rows(row for outcome in new.values()
                                         for row in outcome.rows))
        for key, outcome in new.items():
            self._rows[key] = list(outcome.rows)
            self._details_by_key[key] = details[key]
        return list(new.values())

    def rows(self, keys: Iterable[TrialKey] | None = None) -> list[TrialRow]:
        """Recorded rows, in (case, trial) order, restricted to ``keys`` if given."""
        chosen = sorted(self._rows if keys is None else set(keys) & set(self._rows))
        return [row for key in chosen for row in self._rows[key]]

    def details(self, keys: Iterable[TrialKey] | None = None) -> list[dict[str, Any]]:
        """Recorded detail documents, in (case, trial) order, restricted to ``keys`` if given."""
        chosen = sorted(self._details_by_key if keys is None
                        else set(keys) & set(self._details_by_key))
        return [self._details_by_key[key] for key in chosen]


def open_store(plan: StudyPlan, folder: str | Path) -> StudyStore:
    """The study folder for ``plan``; refuses one made from a different scenario or methods."""
    manifest = {"scenario": plan.document, "methods": list(plan.methods),
                "source": str(plan.source)}
    return StudyStore(folder, manifest, plan.source)
