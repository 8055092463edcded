"""What a study runs: the scenario's ``[study]`` table, its sweep points and its methods.

The twin's scenario validator passes ``[study]`` through unread; this module owns its schema::

    [study]
    trials = 10                  # trials per sweep point (default 10); --trials overrides
    methods = ["all"]            # method names or paper aliases, or "all"; --methods overrides
    workspace_poses = 500        # random poses where the flange error against the truth is taken
    sweep = { "encoder.sigma_mm" = [0.005, 0.01, 0.02] }   # optional sweep points

A sweep maps dotted scenario keys to lists of values; with several keys the lists are zipped
(equal lengths). Each point is the scenario with those keys replaced, validated again by the
twin's own parser. Trial k uses the same seed at every sweep point (common random numbers), so
points differ by the swept setting only.
"""

from __future__ import annotations

import copy
import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from twin.choices import MAX_POSES, MAX_TRIALS
from twin.errors import InputError
from twin.io.paths import read_bytes, read_toml
from twin.io.robot_file import robot_files
from twin.io.table import Table
from twin.scenario import Scenario, parse_scenario
from twin.solvers import SOLVERS, get_solver

STUDY_KEYS = ("trials", "methods", "workspace_poses", "sweep")
DEFAULT_TRIALS = 10
DEFAULT_WORKSPACE_POSES = 500
MAX_SWEEP_POINTS = 1000
"""Most sweep points: each is a whole scenario, copied and validated again before any trial."""
MAX_STUDY_TRIALS = 1_000_000
"""Most trials of a study in all (sweep points × trials per point)."""


@dataclass(frozen=True)
class Case:
    """One sweep point: its label ("" without a sweep) and its validated scenario."""

    label: str
    scenario: Scenario


@dataclass(frozen=True)
class StudyPlan:
    """A validated study.

    Attributes:
        source: The scenario file.
        document: The study's identity: the parsed scenario document less ``[study] trials``
            and ``methods`` and the ``[expect]`` table (what a check asks of the results, not
            what the trials are), plus digests of the robot model and pose plan it names.
        cases: The sweep points, at least one.
        methods: Method names, in the registry's order when "all".
        trials: Trials per case.
        workspace_poses: Random poses for the flange error against the truth.
    """

    source: Path
    document: dict[str, Any]
    cases: tuple[Case, ...]
    methods: tuple[str, ...]
    trials: int
    workspace_poses: int

    @property
    def seed(self) -> int:
        """The scenario's seed, from which every trial's seed derives."""
        return self.cases[0].scenario.seed

    @property
    def keys(self) -> list[tuple[str, int]]:
        """Every (case label, trial) of the study, in order."""
        return [(case.label, trial) for case in self.cases for trial in range(self.trials)]


def resolve_methods(names: list[str] | tuple[str, ...], source: str | Path) -> tuple[str, ...]:
    """Method names for names or aliases; ``all`` is every registered method."""
    if any(name.strip().lower() == "all" for name in names):
        return tuple(SOLVERS)
    resolved: list[str] = []
    for name in names:
        try:
            solver = get_solver(name)
        except InputError as exc:
            raise InputError(exc.found, exc.expected, source=source) from None
        if solver.name not in resolved:
            resolved.append(solver.name)
    if not resolved:
        raise InputError("no methods", "at least one method name, or all", source=source)
    return tuple(resolved)


def _replace(document: dict[str, Any], dotted: str, value: Any, source: Path) -> None:
    *tables, key = dotted.split(".")
    node = document
    for table in tables:
        child = node.setdefault(table, {})
        if not isinstance(child, dict):
            raise InputError(f"sweep key {dotted!r} through a non-table", "a dotted key "
                             "into the scenario's tables", source=source, where="[study] sweep")
        node = child
    node[key] = value


def _sweep_points(study: Table) -> list[dict[str, Any]]:
    sweep = study.table("sweep", expected='a table of dotted keys to lists, e.g. '
                        '{ "encoder.sigma_mm" = [0.005, 0.01] }')
    if not sweep.values:
        return [{}]
    lengths = {len(v) if isinstance(v, list) else -1 for v in sweep.values.values()}
    if len(lengths) != 1 or min(lengths) < 1:
        raise study.error("sweep", "lists of lengths " + ", ".join(map(str, sorted(lengths))),
                          "non-empty lists of equal length")
    count = lengths.pop()
    if count > MAX_SWEEP_POINTS:
        raise study.error("sweep", f"{count} sweep points",
                          f"at most {MAX_SWEEP_POINTS} values per key")
    for key in sweep.values:
        if key.split(".")[0] == "study" or key == "seed":
            raise study.error("sweep", f"sweep key {key!r}", "a key of the simulated scenario "
                              "(not [study] or the seed)")
    return [{key: values[i] for key, values in sweep.values.items()} for i in range(count)]


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()[:16]


def load_study(path: str | Path, *, trials: int | None = None,
               methods: list[str] | None = None, stop: str | None = None) -> StudyPlan:
    """Read a scenario file and its ``[study]`` table.

    Args:
        path: The scenario TOML.
        trials: Trials per case; overrides ``[study] trials``.
        methods: Method names or aliases; overrides ``[study] methods``.
        stop: Stopping protocol; overrides ``[calibration] stop`` (and so is part of the
            study's identity, like any scenario key).

    Raises:
        InputError: naming the file and key that are wrong.
    """
    path = Path(path)
    document = read_toml(path, "a scenario TOML file")
    if stop is not None:
        calibration = document.setdefault("calibration", {})
        if isinstance(calibration, dict):
            calibration["stop"] = stop
    base = parse_scenario(document, path)
    study = Table(base.study, path, "[study]", allowed=STUDY_KEYS)
    if trials is not None and trials < 1:
        raise InputError(f"{trials}", "an integer >= 1", source="--trials")
    n_trials = trials if trials is not None else study.integer(
        "trials", DEFAULT_TRIALS, minimum=1, maximum=MAX_TRIALS)
    workspace = study.integer("workspace_poses", DEFAULT_WORKSPACE_POSES, minimum=1,
                              maximum=MAX_POSES)
    if methods is None:
        chosen = resolve_methods(study.strings(
            "methods", ["all"], expected='a list of method names, e.g. ["lm", "m9"]'), path)
    else:
        chosen = resolve_methods(methods, "--methods")
    points = _sweep_points(study)
    if len(points) * n_trials > MAX_STUDY_TRIALS:
        raise InputError(f"{len(points)} sweep points × {n_trials} trials",
                         f"at most {MAX_STUDY_TRIALS} trials in all",
                         source="--trials" if trials is not None else path,
                         where=None if trials is not None else "[study] trials")
    cases = []
    for point in points:
        if not point:
            cases.append(Case("", base))
            continue
        changed = copy.deepcopy(document)
        for key, value in point.items():
            _replace(changed, key, value, path)
        label = ", ".join(f"{key}={value}" for key, value in point.items())
        try:
            cases.append(Case(label, parse_scenario(changed, path)))
        except InputError as exc:
            raise InputError(exc.found, exc.expected, source=path,
                             where=f"[study] sweep point {label}: {exc.where}") from None
    identity = copy.deepcopy(document)
    # Editing an expectation must not invalidate the trials already run.
    identity.pop("expect", None)
    identity.get("study", {}).pop("trials", None)
    identity.get("study", {}).pop("methods", None)
    # Files the scenario names are part of it: a changed robot model or pose plan is a change.
    identity["files"] = {"robot": _digest("".join(robot_files(base.robot).values())
                                          .encode("utf-8"))}
    if base.pose_plan is not None:
        identity["files"]["poses.plan"] = _digest(
            read_bytes(base.pose_plan, "a pose plan CSV")) \
            if base.pose_plan.is_file() else "missing"
    return StudyPlan(source=path, document=identity, cases=tuple(cases), methods=chosen,
                     trials=n_trials, workspace_poses=workspace)
