"""`twin check`: expectations, their verdicts and exit codes, JUnit XML, baselines."""

from __future__ import annotations

import csv
import itertools
import math
import statistics
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from test_study import SCENARIO, write_scenario

from twin.cli import main
from twin.errors import InputError
from twin.study.baseline import MIN_CHANGED, Metric, compare
from twin.study.expect import STATS, measure_expectation, parse_expect_table, parse_expectation
from twin.testing import check

PASSING = "crlb_ratio median <= 3.0"
"""LM on rigid Gaussian data is near the Cramér–Rao bound (ratio ~1)."""
FAILING = "crlb_ratio median <= 0.5"
"""No unbiased estimator beats the bound by half on the median of four trials."""


def scenario_text(expect: str, *, study: str = 'trials = 4\nmethods = ["lm"]',
                  calibration: str = "", seed: int = 11) -> str:
    """The small test scenario (40 poses) with another [study], [calibration] and [expect]."""
    text = SCENARIO.split("[study]")[0].replace("seed = 11", f"seed = {seed}")
    if calibration:
        text += f"[calibration]\n{calibration}\n\n"
    return text + f"[study]\n{study}\nworkspace_poses = 200\n\n[expect]\n{expect}\n"


def results(folder: Path) -> list[dict[str, str]]:
    """The rows of a study folder's results.csv, read with the csv module."""
    with (folder / "results.csv").open(newline="") as handle:
        return list(csv.DictReader(handle))


def column(folder: Path, method: str, name: str, trials: int | None = None) -> list[float]:
    """One method's values of a column, in trial order (the first ``trials`` only if given)."""
    rows = sorted((r for r in results(folder) if r["method"] == method),
                  key=lambda r: int(r["trial"]))
    return [float(r[name]) for r in rows if trials is None or int(r["trial"]) < trials]


@pytest.mark.parametrize(("text", "found"), [
    ("flange_error_mm p95 <=", "3 words"),
    ("flange_mm p95 <= 0.03", "unknown column 'flange_mm'"),
    ("flange_error_mm p96 <= 0.03", "unknown statistic 'p96'"),
    ("flange_error_mm p95 =< 0.03", "unknown operator '=<'"),
    ("flange_error_mm p95 <= small", "the value 'small'"),
    ("flange_error_mm p95 <= nan", "the value 'nan'"),
    ("converged mean >= 0.9", "mean of the boolean column converged"),
    ("flange_error_mm share >= 0.9", "share of the numeric column flange_error_mm"),
    ("converged share >= 1.5", "the share 1.5"),
    ("method p50 <= 1", "unknown column 'method'"),
])
def test_malformed_expectation_names_file_method_and_string(text: str, found: str) -> None:
    """Each malformed string is one InputError naming the file, the method and the string."""
    with pytest.raises(InputError) as error:
        parse_expect_table({"lm": [text]}, ("lm",), "my.toml")
    message = str(error.value)
    assert message.startswith("my.toml: [expect] lm: found ") and repr(text) in message
    assert found in message and "expected" in message


def test_expect_table_keys() -> None:
    """Aliases and comma-separated names resolve; "*" is every method of the study; a method
    not in the study, or a value that is not a list, is refused listing what is valid."""
    pairs = parse_expect_table({"m2, ekf": [PASSING], "*": ["converged share >= 0.9"]},
                               ("ekf", "lm"), "f.toml")
    assert [(m, e.text) for m, e in pairs] == [
        ("lm", PASSING), ("ekf", PASSING), ("ekf", "converged share >= 0.9"),
        ("lm", "converged share >= 0.9")]
    with pytest.raises(InputError, match=r"\[expect\] pso: found method 'pso', which is not in "
                       r"this study, expected one of the study's methods \(ekf, lm\)"):
        parse_expect_table({"pso": [PASSING]}, ("ekf", "lm"), "f.toml")
    with pytest.raises(InputError, match=r"\[expect\] lm: found 'crlb_ratio"):
        parse_expect_table({"lm": PASSING}, ("lm",), "f.toml")
    with pytest.raises(InputError, match=r"\[expect\]: found \{\}"):
        parse_expect_table({}, ("lm",), "f.toml")


def test_statistics_match_the_standard_library() -> None:
    """Every STAT against Python's statistics module (quantiles 'inclusive' = linear
    interpolation between order statistics); share is the share of true."""
    values = np.random.default_rng(5).lognormal(size=13).tolist()
    percentiles = statistics.quantiles(values, n=100, method="inclusive")
    reference = {"mean": statistics.fmean(values), "median": statistics.median(values),
                 "rms": math.sqrt(statistics.fmean(v * v for v in values)),
                 "min": min(values), "max": max(values), "std": statistics.stdev(values),
                 **{f"p{q}": percentiles[q - 1] for q in (5, 10, 25, 75, 90, 95, 99)}}
    for stat in STATS:
        if stat == "share":
            flags = [True, False, True, True]
            share = parse_expectation("converged share >= 0.5", "f", "lm")
            measured = measure_expectation(share, flags)
            assert measured.value == pytest.approx(0.75)
            continue
        expectation = parse_expectation(f"flange_error_mm {stat} <= 1", "f", "lm")
        assert measure_expectation(expectation, values).value == pytest.approx(reference[stat],
                                                                               rel=1e-12)
    one = measure_expectation(parse_expectation("flange_error_mm std <= 1", "f", "lm"), [0.1])
    assert math.isnan(one.value) and "2 trials" in one.note


@pytest.mark.slow
def test_one_pass_one_fail_then_only_the_pass(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    """One passing and one failing expectation: exit 1, a line each with the measured value,
    a total line, and JUnit XML with two test cases and one failure. With only the passing one
    (an --expect file, then the scenario's own table edited), exit 0, and the study is resumed,
    not run again: an expectation is not part of the study's identity."""
    path = write_scenario(tmp_path, scenario_text(f'lm = ["{PASSING}", "{FAILING}"]'))
    out, junit = tmp_path / "out", tmp_path / "report.xml"
    assert main(["check", str(path), "--out", str(out), "--junit", str(junit)]) == 1
    lines = capsys.readouterr().out.splitlines()
    median = statistics.median(column(out, "lm", "crlb_ratio"))
    assert 0.5 < median < 3.0
    assert lines[1].split() == ["method", "expectation", "measured", "verdict"]
    assert lines[2].split() == ["lm", *PASSING.split(), f"{median:.4g}", "PASS"]
    assert lines[3].split() == ["lm", *FAILING.split(), f"{median:.4g}", "FAIL"]
    assert lines[4] == "total: 2 expectations, 1 passed, 1 failed -> FAIL"

    root = ET.parse(junit).getroot()
    cases = root.findall("./testsuite/testcase")
    assert [c.get("name") for c in cases] == [PASSING, FAILING]
    assert [c.get("classname") for c in cases] == ["study_test.lm"] * 2
    assert cases[0].find("failure") is None
    failure = cases[1].find("failure")
    assert failure is not None and f"measured {median:.4g}" in failure.get("message", "")
    assert (root.get("tests"), root.get("failures")) == ("2", "1")

    csv_before = (out / "results.csv").read_bytes()
    only = tmp_path / "only_pass.toml"
    only.write_text(f'[expect]\nlm = ["{PASSING}"]\n')
    assert main(["check", str(path), "--out", str(out), "--expect", str(only), "--junit",
                 str(junit), "--no-figures"]) == 0
    assert capsys.readouterr().out.splitlines()[-1].endswith("1 passed, 0 failed -> PASS")
    assert [c.get("name") for c in ET.parse(junit).getroot().iter("testcase")] == [PASSING]
    write_scenario(tmp_path, scenario_text(f'lm = ["{PASSING}"]'))
    assert main(["check", str(path), "--out", str(out), "--no-figures"]) == 0
    assert (out / "results.csv").read_bytes() == csv_before


def test_user_errors_are_one_line_and_run_nothing(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """A malformed expectation, a scenario without [expect], an --expect file with other keys,
    a method not in the study and a bad --tolerance: one line on stderr, exit code 2, and no
    study folder made."""
    out = tmp_path / "out"
    bad = write_scenario(tmp_path, scenario_text('lm = ["flange_error_mm p95 <= tiny"]'))
    good = write_scenario(tmp_path, scenario_text(f'lm = ["{PASSING}"]'), "good.toml")
    without = write_scenario(tmp_path, SCENARIO, "without.toml")
    other = tmp_path / "other.toml"
    other.write_text('name = "x"\n[expect]\nlm = ["flange_error_mm max <= 1"]\n')
    cases = [
        (["check", str(bad)], f"{bad}: [expect] lm: found 'flange_error_mm p95 <= tiny': the "
         "value 'tiny'"),
        (["check", str(without)], f"{without}: found no [expect] table"),
        (["check", str(bad), "--expect", str(other)],
         f"{other}: found unknown key 'name', expected only expect"),
        (["check", str(good), "--methods", "ekf"], "found method 'lm', which is not in this "
         "study, expected one of the study's methods (ekf)"),
    ]
    for argv, message in cases:
        assert main([*argv, "--out", str(out)]) == 2
        stderr = capsys.readouterr().err
        assert stderr.startswith("twin: error: ") and message in stderr
        assert stderr.count("\n") == 1, stderr
        assert not out.exists()
    for tolerance in ("5", "-1%", "five"):
        assert main(["check", str(bad), "--out", str(out), f"--tolerance={tolerance}"]) == 2
        stderr = capsys.readouterr().err
        assert f"found {tolerance!r}, expected a relative tolerance" in stderr
        assert stderr.count("\n") == 1, stderr


@pytest.mark.slow
def test_sweep_points_are_checked_one_by_one_and_nan_fails(tmp_path: Path) -> None:
    """Each sweep point is checked on its own. Without any noise the Cramér–Rao bound is zero
    and crlb_ratio NaN: an expectation on it fails and says how many trials were non-finite,
    while the flange error, finite, passes."""
    text = scenario_text('lm = ["crlb_ratio median <= 3.0", "flange_error_mm max <= 0.1"]',
                         study='trials = 2\nmethods = ["lm"]\n'
                         'sweep = { "encoder.sigma_mm" = [0.0, 0.01] }')
    report = check(write_scenario(tmp_path, text), tmp_path / "out", figures=False)
    verdicts = [(r.case, r.expectation.text.split()[0], r.passed) for r in report.results]
    assert verdicts == [("encoder.sigma_mm=0.0", "crlb_ratio", False),
                        ("encoder.sigma_mm=0.0", "flange_error_mm", True),
                        ("encoder.sigma_mm=0.01", "crlb_ratio", True),
                        ("encoder.sigma_mm=0.01", "flange_error_mm", True)]
    nan = report.results[0]
    assert math.isnan(nan.value) and nan.nonfinite == 2 and "2 of 2 trials non-finite" in nan.note
    assert "n/a (2 of 2 trials non-finite)" in report.text
    assert report.text.splitlines()[1].split()[:2] == ["case", "method"]
    assert not report.passed


def test_python_api_in_three_lines(tmp_path: Path) -> None:
    """The documented pattern: check(...) with expectations as a mapping, then assert."""
    path = write_scenario(tmp_path, scenario_text(f'lm = ["{FAILING}"]'))
    report = check(path, tmp_path / "out", trials=2, expect={"lm": [PASSING]}, figures=False)
    assert report.passed, report.text
    (result,) = report.results
    assert result.value == pytest.approx(statistics.median(column(tmp_path / "out", "lm",
                                                                  "crlb_ratio")))
    assert (result.trials, result.method, result.expectation.op) == (2, "lm", "<=")


def exact_one_sided_p(worse: list[float]) -> float:
    """P(W+ >= observed) under H0 by enumerating every sign assignment (no ties, no zeros)."""
    ranks = np.argsort(np.argsort(np.abs(worse))) + 1
    observed = sum(r for r, d in zip(ranks, worse, strict=True) if d > 0)
    totals = [sum(r for r, s in zip(ranks, signs, strict=True) if s)
              for signs in itertools.product((False, True), repeat=len(worse))]
    return sum(t >= observed for t in totals) / len(totals)


def test_compare_decides_with_significance_size_and_direction() -> None:
    """Worse by 50 % in all of 6 trials: a regression, p = 2^-6 exactly; in 4: inconclusive
    (the test cannot reach 0.05); worse by 1 %: within the tolerance; a higher-is-better
    metric that rose: no regression."""
    lower = Metric("lm", "flange_error_mm", True)
    base = [0.010, 0.012, 0.011, 0.013, 0.009, 0.014]
    worse = [b * f for b, f in zip(base, (1.5, 1.4, 1.6, 1.3, 1.75, 1.45), strict=True)]
    regression = compare("", lower, range(6), worse, base, 0.05)
    assert regression.verdict == "regression" and regression.p_value == pytest.approx(2 ** -6)
    differences = [w - b for w, b in zip(worse, base, strict=True)]
    assert [t for t, _ in regression.moved] == sorted(range(6), key=lambda t: -differences[t])[:3]
    assert MIN_CHANGED == 5
    assert compare("", lower, range(4), worse[:4], base[:4], 0.05).verdict == "inconclusive"
    slight = [b * 1.01 for b in base]
    assert compare("", lower, range(6), slight, base, 0.05).verdict == "pass"
    higher = Metric("lm", "validation_rmse_mm", False)
    assert compare("", higher, range(6), worse, base, 0.05).verdict == "pass"
    share = Metric("lm", "converged", False)
    dropped = compare("", share, range(6), [0, 0, 0, 0, 0, 1], [1] * 6, 0.05)
    assert dropped.verdict == "regression" and dropped.relative == pytest.approx(-5 / 6)


@pytest.mark.slow
def test_baseline_flags_a_capped_solver_and_passes_an_unchanged_one(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The same scenario (errors of 2 mm and 0.3°) with every method capped at 2 iterations,
    against a baseline study of it as is: the EKF, which needs 6–8 passes from there, regresses
    (p-value checked against an exact enumeration over the paired differences), LM, whose
    second step already lands within the noise of its optimum, does not; JUnit carries the
    regression. With 3 trials the test cannot reach p < 0.05 and the report says so instead of
    passing it."""
    expect = '"lm,ekf" = ["flange_error_mm median <= 0.1"]'
    study = 'trials = 8\nmethods = ["lm", "ekf"]'

    def larger_errors(text: str) -> str:
        for old, new in (("a_mm = 1.0", "a_mm = 2.0"), ("d_mm = 1.0", "d_mm = 2.0"),
                         ("alpha_deg = 0.1", "alpha_deg = 0.3"),
                         ("theta_deg = 0.1", "theta_deg = 0.3")):
            assert old in text
            text = text.replace(old, new)
        return text

    base = write_scenario(tmp_path, larger_errors(scenario_text(expect, study=study)),
                          "base.toml")
    capped = write_scenario(tmp_path, larger_errors(scenario_text(
        expect, study=study, calibration="max_iterations = 2")), "capped.toml")
    assert main(["check", str(base), "--out", str(tmp_path / "base"), "--no-figures"]) == 0
    capsys.readouterr()
    junit = tmp_path / "report.xml"
    code = main(["check", str(capped), "--out", str(tmp_path / "capped"), "--no-figures",
                 "--baseline", str(tmp_path / "base"), "--junit", str(junit)])
    output = capsys.readouterr().out
    assert code == 1, output
    rows = {line.split()[0]: line.split() for line in output.splitlines()
            if "flange_error_mm  lower" in line}
    assert rows["ekf"][8] == "REGRESSION" and rows["lm"][8] == "PASS", output
    now = column(tmp_path / "capped", "ekf", "flange_error_mm")
    before = column(tmp_path / "base", "ekf", "flange_error_mm")
    difference = [n - b for n, b in zip(now, before, strict=True)]
    assert float(rows["ekf"][7]) == pytest.approx(exact_one_sided_p(difference), rel=1e-3)
    assert rows["ekf"][5] == f"{statistics.median(difference):+.4g}"
    worst = int(np.argmax(difference))
    assert f"trial {worst} {difference[worst]:+.4g}" in output
    assert output.splitlines()[-1].endswith("1 regressed, 0 inconclusive -> FAIL")
    failures = [c for c in ET.parse(junit).getroot().iter("testcase")
                if c.find("failure") is not None]
    assert [c.get("classname") for c in failures] == ["study_test.ekf.baseline"]

    assert main(["check", str(capped), "--out", str(tmp_path / "capped"), "--no-figures",
                 "--trials", "3", "--baseline", str(tmp_path / "base"), "--junit",
                 str(junit)]) == 0
    output = capsys.readouterr().out
    assert f"fewer than {MIN_CHANGED} changed trials" in output
    verdicts = {line.split()[0]: line.split()[8] for line in output.splitlines()
                if "flange_error_mm  lower" in line}
    assert verdicts["ekf"] == "INCONCLUSIVE", output
    skipped = ET.parse(junit).getroot()
    assert skipped.get("skipped") == str(list(verdicts.values()).count("INCONCLUSIVE"))
    assert skipped.get("failures") == "0"


def test_baseline_of_other_seeds_or_trials_is_refused(tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    """A baseline drawn from another seed, one with no trial of this study (another sweep),
    one without a method compared, and a folder without results.csv: exit code 2."""
    expect = 'lm = ["flange_error_mm median <= 0.1"]'
    one = 'trials = 1\nmethods = ["lm"]'
    path = write_scenario(tmp_path, scenario_text(expect, study=one))
    seeds = write_scenario(tmp_path, scenario_text(expect, study=one, seed=12), "seed12.toml")
    swept = write_scenario(tmp_path, scenario_text(
        expect, study=one + '\nsweep = { "encoder.sigma_mm" = [0.01] }'), "swept.toml")
    ekf = write_scenario(tmp_path, scenario_text('ekf = ["flange_error_mm median <= 0.1"]',
                                                 study='trials = 1\nmethods = ["ekf"]'),
                         "ekf.toml")
    for scenario in (seeds, swept, ekf):
        check(scenario, tmp_path / scenario.stem, figures=False)
    capsys.readouterr()
    for folder, message in [
        ("seed12", "found trial 0 with seed"),
        ("swept", "found no trial of this study in"),
        ("ekf", "found no lm in"),
        ("nothing", "results.csv: found no such file"),
    ]:
        assert main(["check", str(path), "--out", str(tmp_path / "out"), "--baseline",
                     str(tmp_path / folder)]) == 2
        stderr = capsys.readouterr().err
        assert message in stderr and stderr.count("\n") == 1, stderr
    assert not (tmp_path / "out").exists()
