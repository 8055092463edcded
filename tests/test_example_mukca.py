"""The real data set of examples/panda_mukca: its README's table is what its command prints."""

from __future__ import annotations

import importlib.util
import re
import shlex
import sys
from pathlib import Path

import pytest

from twin.cli import main

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "panda_mukca"


@pytest.mark.slow
def test_the_readme_command_reproduces_the_documented_table(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """evaluate.py, run afresh on the shipped files (imported by `twin import`), gives the
    README's table digit for digit (seeded, deterministic), and calibration removes most of the
    nominal model's held-out error on every placement."""
    spec = importlib.util.spec_from_file_location("mukca_evaluate", EXAMPLE / "evaluate.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, spec.name, module)
    spec.loader.exec_module(module)
    rows = module.evaluate(module.import_data(tmp_path))
    fresh = module.markdown_table(module.HEADER, rows)
    readme = (EXAMPLE / "README.md").read_text(encoding="utf-8")
    block = re.search(r"<!-- BEGIN GENERATED mukca -->\n(.*?)<!-- END GENERATED mukca -->",
                      readme, re.DOTALL)
    assert block is not None and fresh in block[1]
    assert re.search(r"Measured at commit `[0-9a-f]{7,}`", block[1])
    for row in rows[:3]:
        assert float(row[4]) < 0.2 * float(row[3])


@pytest.mark.slow
def test_the_readme_commands_by_hand_give_the_tables_last_row(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """The README's `twin import` and `twin calibrate` lines, run as written (out/ moved under
    a temporary folder), print the table's random-split row: RMSE nominal and calibrated."""
    readme = (EXAMPLE / "README.md").read_text(encoding="utf-8")
    block = readme.split("The same data by hand", 1)[1].split("```sh\n", 1)[1].split("```")[0]
    lines = block.replace("\\\n", " ").splitlines()
    root = EXAMPLE.parents[1]
    monkeypatch.chdir(root)
    data = str(root / "examples" / "panda_mukca" / "data")
    commands = [shlex.split(line.replace("$D", data).replace("out/", f"{tmp_path}/"))
                for line in lines if line.startswith("$T ")]
    assert [command[1] for command in commands] == ["import", "calibrate"]
    for command in commands:
        expanded = [str(path) for word in command[2:]
                    for path in (sorted(Path("/").glob(word.lstrip("/"))) if "*" in word
                                 else [word])]
        assert main([command[1], *expanded]) == 0
    printed = capsys.readouterr().out
    before = re.search(r"before \(valid\.\)\s+(\S+)", printed)
    after = re.search(r"after, validation\s+(\S+)", printed)
    row = re.search(r"\| random 20 % of all \| the other 80 % \| \d+ \| (\S+) \| (\S+) \|",
                    readme)
    assert before and after and row
    assert (f"{float(before[1]):.3f}", f"{float(after[1]):.3f}") == (row[1], row[2])


def test_import_names_each_rows_placement_as_its_session(tmp_path: Path) -> None:
    """`twin import --session-by folder` of the six files: a session per placement, every row
    of a file in its folder's; `--session-by file` a session per socket file."""
    from twin.io.measurements import load_measurements
    from twin.io.robot_file import load_robot

    robot = load_robot(EXAMPLE.parents[1] / "models" / "panda" / "panda.urdf")
    files = [str(EXAMPLE / "data" / p / f"hole_{h}.csv")
             for p in ("front", "right", "back-high") for h in (0, 1)]
    for by, expected in (("folder", ("front", "right", "back-high")),
                         ("file", tuple(f"{p}/hole_{h}" for p in ("front", "right", "back-high")
                                        for h in (0, 1)))):
        out = tmp_path / f"{by}.csv"
        assert main(["import", *files, "--robot", str(EXAMPLE.parents[1] / "models" / "panda"
                                                       / "panda.urdf"),
                     "--angle-unit", "rad", "--headerless", "--session-by", by,
                     "--out", str(out)]) == 0
        data = load_measurements(out, robot)
        assert data.names("session") == expected
        points = [data.names("point")[j] for j in data.index("point")]
        sessions = [data.names("session")[j] for j in data.index("session")]
        cut = (lambda name: name.split("/")[0]) if by == "folder" else (lambda name: name)
        assert sessions == [cut(point) for point in points]


@pytest.mark.slow
def test_the_cross_validation_block_is_what_its_command_prints(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """The README's generated leave-one-placement-out block: its import and first calibrate
    command, run as written (out/ moved under a temporary folder), print its fold table digit
    for digit, and every held-out placement is scored far below the nominal model."""
    readme = (EXAMPLE / "README.md").read_text(encoding="utf-8")
    block = readme.split("<!-- BEGIN GENERATED mukca-cv -->", 1)[1].split(
        "<!-- END GENERATED mukca-cv -->")[0]
    assert re.search(r"Measured at commit `[0-9a-f]{7,}`", block)
    monkeypatch.chdir(EXAMPLE.parents[1])
    runs = block.split("$ twin ")[1:3]
    for run in runs:
        command = shlex.split(run.splitlines()[0].replace("out/", f"{tmp_path}/"))
        assert main(command) == 0
    printed = capsys.readouterr().out.splitlines()
    table = [line for line in runs[1].splitlines()[1:7]]
    assert printed[1:7] == table
    for line in table[2:5]:
        before, after = (float(v) for v in line.split()[2:4])
        assert after < 0.15 * before


@pytest.mark.slow
def test_holding_what_a_fold_cannot_see_costs_its_fit_nothing(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Each leave-one-placement-out fold of the README's cross-validation, set up as the
    command does: holding the unseen directions (the held-out placement's sockets, the gauge)
    leaves the training objective where LM took it. With a6 and d6 on their bound the polish
    that restores it clipped its steps and gave up: the front fold's fit cost 11.5 %, the
    right fold's 3.7 %, by amounts that changed with the BLAS's rounding."""
    import numpy as np

    from twin.calibration.crossval import final_settings, group_folds
    from twin.calibration.pipeline import solve_many
    from twin.calibration.setup import make_problem
    from twin.cli import build_parser
    from twin.cli.inputs import resolve_inputs
    from twin.io.measurements import load_labels, load_measurements

    readme = (EXAMPLE / "README.md").read_text(encoding="utf-8")
    block = readme.split("<!-- BEGIN GENERATED mukca-cv -->", 1)[1]
    monkeypatch.chdir(EXAMPLE.parents[1])
    importing, calibrating = (shlex.split(run.splitlines()[0].replace("out/", f"{tmp_path}/"))
                              for run in block.split("$ twin ")[1:3])
    assert main(importing) == 0
    args = build_parser().parse_args([word for word in calibrating
                                      if word not in ("--cv-by", "session")])
    inputs = resolve_inputs(args)
    data = inputs.measurements_path
    measurements = load_measurements(data, inputs.robot)
    settings = final_settings(inputs.calibration)
    for label, held in group_folds(load_labels(data, "session")):
        train = np.setdiff1d(np.arange(len(measurements)), held)
        split = make_problem(inputs.robot, measurements, rig=inputs.rig, settings=settings,
                             rows=(train, held))
        result = solve_many(inputs.robot, split, ["lm"], report=False)["lm"]
        assert result.held is not None and result.unseen is not None
        assert len(result.unseen.names) >= 5, label  # the held-out sockets at least
        assert abs(result.held.cost_change) < 1e-4, (label, result.held.cost_change)
