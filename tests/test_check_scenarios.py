"""Dogfooding: every shipped scenario's [expect] table holds today, checked by `twin check`.

The expectations were set on 30 trials per scenario (the thresholds and what was measured are in
each file); here each scenario runs its first 3 trials with the methods its table names, so
that a change that degrades a method's recovery against the truth turns CI red.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from twin.cli import main
from twin.study.check import load_expectations
from twin.study.definition import load_study

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
TRIALS = 3


def expected_methods(path: Path) -> list[str]:
    """The methods a scenario's [expect] table names, in the study's order."""
    plan = load_study(path)
    named = {method for method, _ in load_expectations(plan, None)}
    return [method for method in plan.methods if method in named]


@pytest.mark.slow
@pytest.mark.parametrize("path", sorted(SCENARIOS.glob("*.toml")), ids=lambda p: p.stem)
def test_shipped_expectations_hold(path: Path, tmp_path: Path,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    """`twin check` of the scenario exits 0: every expectation passes, each on its own line."""
    methods = expected_methods(path)
    code = main(["check", str(path), "--out", str(tmp_path / "study"), "--trials", str(TRIALS),
                 "--no-figures",
                 "--methods", ",".join(methods)])
    output = capsys.readouterr().out
    print(output)
    lines = output.splitlines()
    assert code == 0, output
    assert lines[-1].endswith("-> PASS") and " 0 failed" in lines[-1]
    verdicts = [line.split()[-1] for line in lines[2:-1]]
    assert verdicts and set(verdicts) == {"PASS"}


@pytest.mark.slow
def test_shipped_expectations_catch_a_capped_solver(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """The geometric scenario with every method capped at 1 iteration (a real setting, no
    mock) fails its own shipped expectations: LM stops short of the Cramér–Rao bound."""
    source = SCENARIOS / "geometric_irb120.toml"
    text = source.read_text(encoding="utf-8")
    robot = (SCENARIOS.parent / "models" / "irb120.toml").as_posix()
    capped = tmp_path / "geometric_capped.toml"
    text = text.replace('robot = "../models/irb120.toml"', f'robot = "{robot}"')
    capped.write_text(text.replace("[calibration]\n", "[calibration]\nmax_iterations = 1\n"),
                      encoding="utf-8")
    code = main(["check", str(capped), "--out", str(tmp_path / "study"), "--trials", str(TRIALS),
                 "--no-figures", "--methods", ",".join(expected_methods(source))])
    output = capsys.readouterr().out
    assert code == 1, output
    failed = {tuple(line.split()[:2]) for line in output.splitlines() if line.endswith("FAIL")}
    assert ("lm", "crlb_ratio") in failed and ("lm", "converged") in failed, output
