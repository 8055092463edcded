"""A study's folder: `results.csv` and `trials.jsonl` appended durably, `study.json` for resume.

Every finished trial is appended as one write of its JSON detail line (histories, residuals,
parameter errors) to `trials.jsonl`, then one write of its rows (one per method) to
`results.csv`, each followed by an fsync. `results.csv` is the record of what is finished: on
reopening, a torn last line (the run was killed mid-write) and any trial with fewer rows than
methods are dropped, and detail lines of trials not in the CSV are dropped, so every trial is
counted exactly once whatever point a run was killed at.

`study.json` holds the study's fingerprint: the parsed scenario document (less the number of
trials, which may grow between runs) and the methods. A run whose fingerprint differs is refused
with an :class:`~twin.errors.InputError` that names the first difference.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import os
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

from twin.errors import InputError
from twin.io.atomic import WRITE_EXPECTED, write_atomic
from twin.io.paths import os_error, read_json, read_text

RESULTS = "results.csv"
DETAILS = "trials.jsonl"
MANIFEST = "study.json"

STAGES = ("before", "train", "validation")
METRIC_KEYS = ("rmse", "mae", "std", "max")
COLUMNS = (
    "trial", "case", "seed", "method",
    *(f"{stage}_{key}_mm" for stage in STAGES for key in METRIC_KEYS),
    "flange_error_mm", "crlb_mm", "crlb_ratio",
    "iterations", "evaluations", "seconds", "converged", "stop_reason",
    "flange_error_gauge_free_mm", "crlb_ratio_gauge_free", "point_error_mm", "point_crlb_ratio",
)
"""Columns of `results.csv`, one row per trial × method. Lengths in mm; ``mae`` is the paper's
"STD"; ``flange_error_mm`` is the RMS flange-position error over the workspace against the truth,
``crlb_mm`` its Cramér–Rao bound and ``crlb_ratio`` their ratio; ``converged`` is true when a
convergence test (ftol, xtol, gtol) fired at the point returned; ``stop_reason`` names the test
that stopped each stage, joined by ``+`` for cascades (``gtol+stalled``);
``flange_error_gauge_free_mm`` is the flange error modulo the motions the data cannot see
(:mod:`twin.gauge`: a turn about joint 1's axis with an estimated port…) and
``crlb_ratio_gauge_free`` its ratio to the bound; ``point_error_mm`` is the same for the
measured point (eyelet, tracker target, ball: what an estimated attachment identifies) and
``point_crlb_ratio`` its ratio to that point's Cramér–Rao bound."""
_INTEGER_COLUMNS = ("trial", "seed", "iterations", "evaluations")

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
    rows: tuple[dict[str, Any], ...]
    """One row per method, keyed by :data:`COLUMNS`."""
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


def _format(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    return str(value)


def _parse(column: str, text: str) -> Any:
    if column in ("case", "method", "stop_reason"):
        return text
    if column == "converged":
        return text == "true"
    if column in _INTEGER_COLUMNS:
        return int(text)
    return float(text)


def parse_results(text: str, source: str | Path) -> tuple[dict[TrialKey, list[dict[str, Any]]],
                                                         bool]:
    """The rows of a `results.csv` text, grouped by trial, and whether its last line was torn
    (and left out).

    Raises:
        InputError: for another header or a line with the wrong number of fields.
    """
    lines = text.splitlines(keepends=True)
    torn = bool(lines) and not lines[-1].endswith("\n")
    if torn:
        lines = lines[:-1]
    if not lines or lines[0].strip() != ",".join(COLUMNS):
        raise InputError(f"{RESULTS} with another header", f"the header {','.join(COLUMNS)}",
                         source=source)
    rows: dict[TrialKey, list[dict[str, Any]]] = {}
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
            row = {c: _parse(c, v) for c, v in zip(COLUMNS, values, strict=True)}
        except ValueError as exc:
            raise InputError(f"a value that is not a number ({exc})", "the rows `twin study` "
                             "writes", source=source, where=f"line {number}") from None
        rows.setdefault((row["case"], row["trial"]), []).append(row)
    return rows, torn


def read_results(folder: str | Path) -> dict[TrialKey, list[dict[str, Any]]]:
    """The finished rows of another study's folder, grouped by trial, read only: a torn last
    line is left out and nothing is repaired or written.

    Raises:
        InputError: if the folder has no readable `results.csv`.
    """
    path = Path(folder) / RESULTS
    text = read_text(path, f"the {RESULTS} of an earlier `twin study` or `twin check` run")
    return parse_results(text, path)[0]


def _append_durably(path: Path, text: str) -> None:
    try:
        with path.open("a", encoding="utf-8") as handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())
    except OSError as exc:
        raise os_error(path, "appending to it", exc, WRITE_EXPECTED) from None


def _read(path: Path, what: str) -> str:
    return read_text(path, f"{what} of an earlier `twin study` run, or a new --out folder",
                     journal=True)


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
        self._rows: dict[TrialKey, list[dict[str, Any]]] = {}
        self._details: dict[TrialKey, dict[str, Any]] = {}
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
                    if sorted(r["method"] for r in group) == sorted(self.methods)}
        details, details_dirty = self._read_details(set(complete))
        if csv_dirty or len(complete) != len(rows):
            text = io.StringIO()
            writer = csv.DictWriter(text, fieldnames=COLUMNS, lineterminator="\n")
            writer.writeheader()
            for group in complete.values():
                writer.writerows({c: _format(r[c]) for c in COLUMNS} for r in group)
            write_atomic(self.results_path, text.getvalue())
        if details_dirty:
            write_atomic(self.details_path, "".join(
                json.dumps(d, sort_keys=True) + "\n" for d in details.values()))
        self._rows, self._details = complete, details

    def _read_rows(self) -> tuple[dict[TrialKey, list[dict[str, Any]]], bool]:
        if not self.results_path.exists():
            write_atomic(self.results_path, ",".join(COLUMNS) + "\n")
            return {}, False
        return parse_results(_read(self.results_path, f"the {RESULTS}"), self.results_path)

    def _read_details(self, finished: set[TrialKey]) -> tuple[dict[TrialKey, dict[str, Any]], bool]:
        if not self.details_path.exists():
            return {}, False
        details: dict[TrialKey, dict[str, Any]] = {}
        dirty = False
        for line in _read(self.details_path, f"the {DETAILS}").splitlines(keepends=True):
            try:
                detail: Any = json.loads(line) if line.endswith("\n") else None
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

    def append(self, outcome: TrialOutcome) -> bool:
        """Record a finished trial durably; a trial already recorded is ignored.

        Returns:
            True if the trial was new.
        """
        if outcome.key in self._rows:
            return False
        detail = {"case": outcome.case, "trial": outcome.trial, "seed": outcome.seed,
                  **outcome.detail}
        _append_durably(self.details_path, json.dumps(detail, sort_keys=True) + "\n")
        text = io.StringIO()
        writer = csv.DictWriter(text, fieldnames=COLUMNS, lineterminator="\n")
        writer.writerows({c: _format(row[c]) for c in COLUMNS} for row in outcome.rows)
        _append_durably(self.results_path, text.getvalue())
        self._rows[outcome.key] = [dict(row) for row in outcome.rows]
        self._details[outcome.key] = detail
        return True

    def rows(self, keys: Iterable[TrialKey] | None = None) -> list[dict[str, Any]]:
        """Recorded rows, in (case, trial) order, restricted to ``keys`` if given."""
        chosen = sorted(self._rows if keys is None else set(keys) & set(self._rows))
        return [row for key in chosen for row in self._rows[key]]

    def details(self, keys: Iterable[TrialKey] | None = None) -> list[dict[str, Any]]:
        """Recorded detail documents, in (case, trial) order, restricted to ``keys`` if given."""
        chosen = sorted(self._details if keys is None else set(keys) & set(self._details))
        return [self._details[key] for key in chosen]
