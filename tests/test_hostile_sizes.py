"""Hostile inputs, class 9 — sizes: a scenario asks for no more than the flags may.

`--trials` and `--poses` are capped where they are parsed; the same sizes written in a
scenario's `[study]` table were not: `trials = 1000000` ran for days, a 1e9-pose workspace
allocated 44.7 GiB after results.csv and study.json were written, a sweep of a million values
copied and parsed the scenario a million times. Each is refused in one line naming the key,
before the study folder exists. They run as processes with a timeout: a regression fails
instead of running for days.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import Refusals

from twin.choices import MAX_TRIALS
from twin.study.definition import MAX_STUDY_TRIALS, MAX_SWEEP_POINTS

ROOT = Path(__file__).resolve().parents[1]
TIMEOUT_S = 60.0
"""Far longer than a refusal takes, far shorter than a study of these sizes."""


def _scenario(tmp_path: Path, name: str, study: str) -> Path:
    """The geometric scenario (its [expect] kept) with a [study] table."""
    text = (ROOT / "scenarios" / "geometric_irb120.toml").read_text()
    text = text.replace('"../models/', f'"{ROOT}/models/')
    path = tmp_path / f"{name}.toml"
    path.write_text(text.replace("[expect]", f"[study]\n{study}\n\n[expect]", 1))
    return path


def _sweep(count: int) -> str:
    return 'sweep = { "encoder.sigma_mm" = [' + ", ".join(["0.01"] * count) + "] }"


@pytest.mark.parametrize(
    ("study", "flags", "match"),
    [
        ("trials = 1000000", [], f"[study] trials: found 1000000, expected an integer in "
         f"1..{MAX_TRIALS}"),
        ('workspace_poses = 1000000000\nmethods = ["lm"]', [], "[study] workspace_poses: found "
         "1000000000, expected an integer in 1..100000"),
        # One past the cap proves the cap; the million values of the report (a 6 MB file) only
        # measured tomllib, 5 s a process.
        (_sweep(MAX_SWEEP_POINTS + 1), [], f"[study] sweep: found {MAX_SWEEP_POINTS + 1} sweep "
         f"points, expected at most {MAX_SWEEP_POINTS} values per key"),
        (f"{_sweep(MAX_SWEEP_POINTS)}\ntrials = 10000", [], f"[study] trials: found "
         f"{MAX_SWEEP_POINTS} sweep points × 10000 trials, expected at most {MAX_STUDY_TRIALS} "
         "trials in all"),
        (_sweep(MAX_SWEEP_POINTS), ["--trials", "5000"], f"--trials: found {MAX_SWEEP_POINTS} "
         f"sweep points × 5000 trials, expected at most {MAX_STUDY_TRIALS}"),
    ],
    ids=["trials", "workspace", "sweep", "trials in all", "--trials in all"],
)
@pytest.mark.slow
@pytest.mark.parametrize("command", ["study", "check"])
def test_a_study_too_big(command: str, study: str, flags: list[str], match: str,
                         tmp_path: Path, refusals: Refusals) -> None:
    """Refused before anything is written: no study folder, the scenario untouched."""
    scenario = _scenario(tmp_path, "big", study)
    refusals.process([command, scenario, "--out", tmp_path / "out", *flags], [scenario], match,
                     timeout=TIMEOUT_S)
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_a_fixture_of_too_many_touches(tmp_path: Path, refusals: Refusals) -> None:
    """Each touch count is within the pose limit, but sockets × placements × touches is not."""
    text = (ROOT / "scenarios" / "fixed_points_irb120.toml").read_text()
    scenario = tmp_path / "touches.toml"
    scenario.write_text(text.replace("touches = 12", "touches = 100000")
                        .replace('"../models/', f'"{ROOT}/models/'))
    refusals.process(["simulate", scenario, "--out", tmp_path / "out"], [scenario],
                     f"{scenario}: [fixture] touches: found 100000 touches of 6 sockets (600000 "
                     "poses), expected at most 100000 poses in all", timeout=TIMEOUT_S)
    assert not (tmp_path / "out").exists()
