"""Studies in one process: the [study] table, trials against the truth, the store, the tables."""

from __future__ import annotations

import csv
import io
import json
import math
import time
from collections import Counter
from pathlib import Path
from types import SimpleNamespace
from typing import get_type_hints

import numpy as np
import pytest

from twin.cli import main
from twin.errors import InputError
from twin.study.definition import load_study
from twin.study.progress import Progress, format_duration
from twin.study.rows import COLUMNS, TrialRow
from twin.study.statistics import table7
from twin.study.store import StudyStore, TrialOutcome, open_store
from twin.study.trial import TrialSpec, run_batch, trial_seed

SCENARIO = """
name = "study_test"
seed = 11

[port]
position_mm = [600.0, -400.0, 100.0]

[perturbation]
a_mm = 1.0
d_mm = 1.0
alpha_deg = 0.1
theta_deg = 0.1

[poses]
count = 40

[encoder]
sigma_mm = 0.01
resolution_mm = 0.0

[study]
trials = 4
methods = ["lm"]
workspace_poses = 200
"""


def write_scenario(folder: Path, text: str = SCENARIO, name: str = "scenario.toml") -> Path:
    """A small rigid scenario (40 poses, LM only) written to ``folder``."""
    path = folder / name
    path.write_text(text, encoding="utf-8")
    return path


def recorded(folder: Path) -> Counter[int]:
    """Rows (one per method) per trial in `results.csv`, whole lines only (none if absent)."""
    path = folder / "results.csv"
    if not path.exists():
        return Counter()
    lines = path.read_text().splitlines(keepends=True)
    whole = [line for line in lines if line.endswith("\n")]
    return Counter(int(row["trial"]) for row in csv.DictReader(whole))


def outcomes(path: Path, keys: list[tuple[str, int]]) -> list[TrialOutcome]:
    """Run the trials ``keys`` of the study at ``path`` in this process."""
    plan = load_study(path)
    specs = {c.label: TrialSpec(c.scenario, plan.methods, plan.workspace_poses)
             for c in plan.cases}
    return run_batch(specs, keys)


def test_study_table_and_overrides(tmp_path: Path) -> None:
    """[study] sets trials and methods; arguments override; aliases resolve to names."""
    path = write_scenario(tmp_path)
    plan = load_study(path)
    assert (plan.trials, plan.methods, plan.workspace_poses) == (4, ("lm",), 200)
    assert plan.keys == [("", k) for k in range(4)]
    plan = load_study(path, trials=2, methods=["m2", "lm"])
    assert (plan.trials, plan.methods) == (2, ("lm",))


def with_study(lines: str) -> str:
    """The test scenario with another [study] table."""
    return SCENARIO.split("[study]")[0] + "[study]\n" + lines + "\n"


@pytest.mark.parametrize(("study", "where"), [
    ("trials = 0", "[study] trials"),
    ("wrong = 1", "[study]"),
    ('methods = ["nope"]', "unknown method"),
    ('sweep = { "encoder.sigma_mm" = [0.01, -1.0] }', "sweep point encoder.sigma_mm=-1.0"),
])
def test_bad_study_table(tmp_path: Path, study: str, where: str) -> None:
    """A wrong [study] key is one InputError naming the file and the key."""
    path = write_scenario(tmp_path, with_study(study))
    with pytest.raises(InputError) as error:
        load_study(path)
    assert str(path) in str(error.value) and where in str(error.value)


def test_sweep_points_share_trial_seeds(tmp_path: Path) -> None:
    """A sweep makes one validated case per value; trial k has the same seed at every point."""
    text = with_study('methods = ["lm"]\nsweep = { "encoder.sigma_mm" = [0.005, 0.02] }')
    plan = load_study(write_scenario(tmp_path, text))
    assert [c.label for c in plan.cases] == ["encoder.sigma_mm=0.005", "encoder.sigma_mm=0.02"]
    assert [c.scenario.noise.sigma_m for c in plan.cases] == pytest.approx([5e-6, 2e-5])
    results = outcomes(tmp_path / "scenario.toml", [(plan.cases[0].label, 1),
                                                    (plan.cases[1].label, 1)])
    assert results[0].seed == results[1].seed == trial_seed(11, 1)
    # Same poses and truth, more noise: the nominal model's error barely moves, the fit's does.
    before = [r.rows[0].before_rmse_mm for r in results]
    assert before[0] == pytest.approx(before[1], rel=0.05)


def test_trial_is_reproducible_and_near_the_bound(tmp_path: Path) -> None:
    """The same trial gives the same numbers; on rigid Gaussian data LM's flange error against
    the truth is of the order of the Cramér–Rao bound, and its identifiable parameter error is
    small while its raw parameter error need not be."""
    path = write_scenario(tmp_path)
    first, again = outcomes(path, [("", 2)]), outcomes(path, [("", 2)])
    timeless = [row._replace(seconds=0.0) for row in first[0].rows]
    assert timeless == [row._replace(seconds=0.0) for row in again[0].rows]
    row = first[0].rows[0]
    types = get_type_hints(TrialRow)
    assert all(type(getattr(row, column)) is types[column] for column in COLUMNS)
    assert row.validation_rmse_mm < 0.1 * row.before_rmse_mm
    # The bound is an unbiased estimator's; holding the weak directions the data cannot tell
    # from zero trades their variance for a bias, so a trial whose truth is small along them
    # lands below it (0.46 here).
    assert 0.3 < row.crlb_ratio < 3.0
    error = np.array(first[0].detail["methods"]["lm"]["parameter_error"])
    units = np.array(first[0].detail["parameter_units"])
    assert np.max(np.abs(error[units == "mm"])) < 0.5


def test_a_batch_gives_each_trial_as_it_runs_alone(tmp_path: Path) -> None:
    """A batch simulates each case's run of trials before it fits them: every outcome is still
    the trial's own — the same numbers as the trial run alone — in the batch's order, across
    cases and back."""
    text = with_study('methods = ["lm"]\nsweep = { "encoder.sigma_mm" = [0.005, 0.02] }')
    path = write_scenario(tmp_path, text)
    first, second = (case.label for case in load_study(path).cases)
    keys = [(first, 0), (first, 1), (second, 1), (first, 2)]
    together = outcomes(path, keys)
    assert [(outcome.case, outcome.trial) for outcome in together] == keys
    for batched, (case, trial) in zip(together, keys, strict=True):
        alone = outcomes(path, [(case, trial)])[0]
        assert [row._replace(seconds=0.0) for row in batched.rows] \
            == [row._replace(seconds=0.0) for row in alone.rows]
        assert batched.detail == alone.detail


def test_store_repairs_a_torn_tail_and_counts_each_trial_once(tmp_path: Path) -> None:
    """A run killed mid-write leaves a torn line: reopening drops it, keeps whole trials, and
    appending a trial already recorded is a no-op."""
    path = write_scenario(tmp_path)
    plan = load_study(path)
    done = outcomes(path, [("", 0), ("", 1)])
    store = open_store(plan, tmp_path / "out")
    assert store.record(done) == done
    with (tmp_path / "out" / "results.csv").open("a") as handle:
        handle.write("2,,123,lm,0.5,0.4")
    with (tmp_path / "out" / "trials.jsonl").open("a") as handle:
        handle.write('{"case": "", "trial": 2, "seed"')
    store = open_store(plan, tmp_path / "out")
    assert store.finished() == {("", 0), ("", 1)}
    assert store.record([done[0], done[0]]) == []
    lines = (tmp_path / "out" / "results.csv").read_text().splitlines()
    assert len(lines) == 3 and lines[0] == ",".join(COLUMNS)
    details = (tmp_path / "out" / "trials.jsonl").read_text().splitlines()
    assert sorted(json.loads(d)["trial"] for d in details) == [0, 1]
    assert store.rows() == [r for o in done for r in o.rows]


def test_changed_scenario_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Resuming a folder with a changed scenario exits with code 2 and names what changed;
    more trials of the same scenario, or its methods named in another order, are allowed."""
    path = write_scenario(tmp_path)
    StudyStore(tmp_path / "out", {"scenario": load_study(path).document, "methods": ["lm"]},
               path)
    write_scenario(tmp_path, SCENARIO.replace("sigma_mm = 0.01", "sigma_mm = 0.02"))
    assert main(["study", str(path), "--out", str(tmp_path / "out")]) == 2
    message = capsys.readouterr().err
    assert "encoder.sigma_mm" in message and str(path) in message and "0.02" in message
    open_store(load_study(path, trials=9, methods=["lm", "pso"]), tmp_path / "out2")
    open_store(load_study(path, trials=12, methods=["m3", "m2"]), tmp_path / "out2")


def _rows(rmse: dict[str, list[float]]) -> list[TrialRow]:
    """Rows with the validation RMSE of each method per trial (other columns NaN)."""
    blank = dict.fromkeys(COLUMNS, math.nan)
    return [TrialRow(**{**blank, "trial": t, "case": "", "method": m, "validation_rmse_mm": v})
            for m, values in rmse.items() for t, v in enumerate(values)]


def test_table7_wilcoxon_and_missing_methods() -> None:
    """M9 lower than LM in all ten trials gives the exact two-sided p = 2/2¹⁰; a study without
    M9 says so instead of testing, and missing paper methods are named."""
    rng = np.random.default_rng(0)
    m9 = rng.uniform(0.2, 0.4, 10)
    result = table7(_rows({"amlm-bipso": list(m9), "lm": list(m9 + 0.05)}), ["lm", "amlm-bipso"])
    assert result["tests"]["lm"]["p_value"] == pytest.approx(2 / 2**10)
    assert result["tests"]["lm"]["verdict"] == "M9 lower (significant)"
    assert "M1" in result["missing"] and "M9" not in result["missing"]
    alone = table7(_rows({"lm": list(m9)}), ["lm"])
    assert not alone["tests"] and "M9 (AMLM-BIPSO) is not in this study" in alone["note"]


def test_progress_plain_lines() -> None:
    """Off a terminal the bar prints plain lines: the start, then always the last one; trials
    resumed from an earlier run count as done but not towards the rate."""
    stream = io.StringIO()
    progress = Progress(total=5, done=2, stream=stream)
    assert "2/5 trials" in stream.getvalue() and "ETA --:--" in stream.getvalue()
    progress.advance(3)
    last = stream.getvalue().splitlines()[-1]
    assert "5/5 trials" in last and last.endswith("done") and "\r" not in stream.getvalue()
    assert format_duration(3725) == "1:02:05" and format_duration(65) == "1:05"


def test_progress_eta_from_the_rate_after_the_first_report(monkeypatch: pytest.MonkeyPatch
                                                           ) -> None:
    """A run's first report pays what the run pays once (imports, the workers' start, numba's
    loading or compiling): the ETA waits for a second report and extrapolates the rate since
    the first, not the first trial's time."""
    from twin.study import progress as module

    clock = [100.0]
    monkeypatch.setattr(module, "time", SimpleNamespace(monotonic=lambda: clock[0]))
    progress = Progress(total=21, stream=io.StringIO())
    clock[0] = 120.0  # the first trial, after 20 s of start
    progress.advance()
    assert progress.line().endswith("0:20 elapsed, ETA --:--")
    clock[0] = 130.0  # a worker's batch of ten in 10 s: 1 s a trial, 10 left
    progress.advance(10)
    assert progress.line().endswith("0:30 elapsed, ETA 0:10")


@pytest.mark.slow
def test_a_note_comes_only_while_a_block_runs_long() -> None:
    """:meth:`Progress.note_after` writes its line above the bar once the block has run that
    long, and nothing for a block that ends before."""
    stream = io.StringIO()
    progress = Progress(total=2, stream=stream)
    with progress.note_after(5.0, "slow"):
        pass
    assert "slow" not in stream.getvalue()
    with progress.note_after(0.05, "slow"):
        time.sleep(0.5)
    lines = stream.getvalue().splitlines()
    assert lines.count("slow") == 1 and "0/2 trials" in lines[-1]


def test_changed_robot_file_is_refused(tmp_path: Path) -> None:
    """The robot model a scenario names is part of the study: editing it is a change too."""
    model = (Path(__file__).resolve().parents[1] / "models" / "irb120.toml").read_text()
    (tmp_path / "robot.toml").write_text(model)
    path = write_scenario(tmp_path, 'robot = "robot.toml"\n' + SCENARIO)
    open_store(load_study(path), tmp_path / "out")
    (tmp_path / "robot.toml").write_text(model.replace("d = 290.0", "d = 291.0", 1))
    with pytest.raises(InputError, match=r"files\.robot"):
        open_store(load_study(path), tmp_path / "out")


@pytest.mark.parametrize("path", sorted((Path(__file__).resolve().parents[1] / "scenarios")
                                        .glob("*.toml")), ids=lambda p: p.name)
def test_every_shipped_scenario_is_a_valid_study(path: Path) -> None:
    """Each scenario file's [study] table (or its absence) makes a valid study."""
    plan = load_study(path)
    assert plan.trials >= 1 and plan.methods and plan.cases


def test_joint_level_truth_columns_are_held_to_the_physical_flange(tmp_path: Path) -> None:
    """With joint-level error groups (the paper's rig: transmission, backlash, compliance) and
    a known port at the flange centre, nothing is gauge-free: the gauge-free column equals the
    flange error against the twin's physical flange, both a few hundredths of a millimetre, and
    the measured point (the flange centre) the same again — not the 0.6 mm of the D-H table
    alone."""
    scenarios = Path(__file__).resolve().parents[1] / "scenarios"
    text = (scenarios / "paper_irb120.toml").read_text().replace(
        'robot = "../models/irb120.toml"', f'robot = "{scenarios.parent}/models/irb120.toml"')
    text = text.replace('stop = "paper"', 'stop = "converge"\n'
                        'errors = ["dh", "transmission", "backlash", "compliance"]')
    text = text.replace("count = 120", "count = 200")
    text = text.replace('methods = ["all"]', 'methods = ["lm"]')
    path = write_scenario(tmp_path, text)
    (row,) = outcomes(path, [("", 0)])[0].rows[:1]
    assert row.flange_error_gauge_free_mm == pytest.approx(row.flange_error_mm, rel=1e-9)
    assert row.point_error_mm == pytest.approx(row.flange_error_mm, rel=1e-9)
    assert row.flange_error_mm < 0.05
