"""Every row used: training on every pose (``--train-fraction 1``), scoring on a separate
file (``--validate``), k-fold and leave-one-group-out cross-validation (``--cv``,
``--cv-by``), and no split that can crash.

Referees: the identified table's cable lengths computed here from its flange positions
(numpy, not the model's residual), and :func:`scipy.optimize.least_squares` on each fold's
training rows."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import least_squares

import twin
from twin.calibration.crossval import cross_validate
from twin.calibration.held_out import held_out_residuals
from twin.calibration.pipeline import solve_many
from twin.calibration.setup import make_problem
from twin.cli import main
from twin.dataset import Measurements
from twin.errors import InputError
from twin.kinds.length import length_measurements
from twin.report.text import format_result
from twin.rig import Rig
from twin.robot import RobotModel, random_poses

PORT = "600,-400,100"


def _lengths(robot: RobotModel, q_rad: np.ndarray, port_m: np.ndarray) -> np.ndarray:
    """Cable lengths of a robot, computed here: flange to port, shape (m,), m."""
    return np.linalg.norm(robot.flange_positions(q_rad) - port_m, axis=1)


def test_every_pose_trains_and_nothing_is_shown_as_validated(
        csv_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
        irb120: RobotModel, measurements: Measurements, port_m: np.ndarray) -> None:
    """``--train-fraction 1``: all 120 poses train, the fit is scipy's on all of them (over the
    directions the answer leaves free: what the data cannot see, or cannot tell from zero, is
    held at the nominal), and the report, the JSON and the history carry no validation
    figure."""
    out = tmp_path / "r.json"
    assert main(["calibrate", str(csv_path), "--port", PORT, "--train-fraction", "1",
                 "--json", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "120 poses, every one trained on" in printed
    assert "after, validation" not in printed and "before (train)" in printed
    document = json.loads(out.read_text())
    assert set(document["metrics"]) == {"before", "train"}
    assert document["validation"] == {"poses": 0, "source": "split", "train_poses": 120}
    assert all(record["validation_rmse"] is None for record in document["history"])
    problem = make_problem(irb120, measurements, port_m,
                           settings=twin.CalibrationSettings(train_fraction=1.0)).problem
    assert len(problem.train) == 120 and len(problem.validation) == 0
    result = twin.calibrate(irb120, measurements, port_m,
                            settings=twin.CalibrationSettings(train_fraction=1.0))
    assert result.unseen is not None
    free = result.unseen.seen_x  # x = x0 + free @ z, the nominal along the held directions
    reference = least_squares(
        lambda z: problem.model.residuals(problem.x0 + free @ z, problem.train),
        np.zeros(free.shape[1]),
        jac=lambda z: problem.model.jacobian(problem.x0 + free @ z, problem.train)[1] @ free,
        method="trf", x_scale="jac")
    assert document["metrics"]["train"]["rmse"] == pytest.approx(
        np.sqrt(np.mean(reference.fun**2)) * 1e3, rel=1e-3)


@pytest.mark.parametrize("share", [0.2, 0.5, 0.9, 0.99, 0.999, 1.0])
@pytest.mark.parametrize("poses", [25, 31, 60, 121])
def test_no_split_can_crash(share: float, poses: int, irb120: RobotModel,
                            measurements: Measurements, port_m: np.ndarray) -> None:
    """Any share of any number of poses either calibrates (with validation poses or without)
    or is refused with an InputError naming the poses needed — never another exception."""
    data = measurements.subset(np.arange(min(poses, len(measurements))))
    settings = twin.CalibrationSettings(train_fraction=share)
    try:
        result = twin.calibrate(irb120, data, port_m, settings=settings)
    except InputError as exc:
        assert "expected at least" in str(exc)
        return
    assert result.train_rows.size + result.validation_rows.size == len(data)
    assert result.validated == (result.validation_rows.size > 0)
    assert format_result(result).count("after, validation") == int(
        result.validated)


def test_a_separate_file_validates(csv_path: Path, tmp_path: Path, irb120: RobotModel,
                                   true_robot: RobotModel, port_m: np.ndarray) -> None:
    """``--validate FILE``: every row of INPUT trains; the validation figures are the
    identified table's lengths against FILE's, computed here."""
    rng = np.random.default_rng(21)
    q = random_poses(irb120, 40, rng)
    other = length_measurements(q, _lengths(true_robot, q, port_m) + rng.normal(0, 1e-5, 40))
    held = tmp_path / "held.csv"
    twin.write_measurements(held, other)
    out = tmp_path / "r.json"
    assert main(["calibrate", str(csv_path), "--port", PORT, "--validate", str(held),
                 "--json", str(out)]) == 0
    document = json.loads(out.read_text())
    assert document["validation"]["source"] == str(held)
    assert document["validation"]["train_poses"] == 120
    identified = irb120.perturbed(twin.load_result(out).delta)
    residuals = _lengths(identified, other.q_rad, port_m) - other.value("length_m")
    assert document["metrics"]["validation"]["rmse"] == pytest.approx(
        np.sqrt(np.mean(residuals**2)) * 1e3, rel=1e-4)
    nominal = _lengths(irb120, other.q_rad, port_m) - other.value("length_m")
    assert document["metrics"]["before"]["rmse"] == pytest.approx(
        np.sqrt(np.mean(nominal**2)) * 1e3, rel=1e-6)


@pytest.mark.slow
def test_k_fold_holds_every_pose_out_once_and_each_fold_is_a_fit(
        irb120: RobotModel, measurements: Measurements, port_m: np.ndarray) -> None:
    """5 folds partition the poses; each fold's held-out RMSE is that of scipy's fit on its
    training rows (lengths computed here), the pooled RMSE that of every held-out row."""
    crossed = cross_validate(irb120, measurements, port_m, folds=5, seed=3)
    rows = np.concatenate([fold.rows for fold in crossed.folds])
    assert sorted(rows.tolist()) == list(range(len(measurements)))
    pooled = []
    for fold in crossed.folds:
        train = np.setdiff1d(np.arange(len(measurements)), fold.rows)
        problem = make_problem(irb120, measurements, port_m, rows=(train, fold.rows)).problem
        fit = least_squares(lambda x, p=problem: p.model.residuals(x, p.train), problem.x0,
                            jac=lambda x, p=problem: p.model.jacobian(x, p.train)[1],
                            bounds=(problem.lower, problem.upper), method="trf",
                            x_scale="jac")
        held = measurements.subset(fold.rows)
        referee = _lengths(irb120.perturbed(problem.model.table(fit.x) - irb120.dh),
                           held.q_rad, port_m) - held.value("length_m")
        pooled.append(referee)
        assert fold.held_out.rmse == pytest.approx(np.sqrt(np.mean(referee**2)), rel=0.05)
    assert crossed.pooled.rmse == pytest.approx(
        np.sqrt(np.mean(np.concatenate(pooled) ** 2)), rel=0.05)
    assert crossed.pooled.rmse < 2e-5 < crossed.pooled_before.rmse


def test_leave_one_group_out_by_a_column(csv_path: Path, tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    """``--cv-by session``: one fold per label, in the order they appear, each group's rows
    held out; the model reported is fitted on every pose."""
    lines = csv_path.read_text().splitlines()
    labels = [("mon", "tue", "wed")[k % 3] for k in range(len(lines) - 1)]
    labelled = tmp_path / "sessions.csv"
    labelled.write_text("\n".join([lines[0] + ",session",
                                   *(f"{line},{label}" for line, label
                                     in zip(lines[1:], labels, strict=True))]) + "\n")
    out = tmp_path / "r.json"
    assert main(["calibrate", str(labelled), "--port", PORT, "--cv-by", "session",
                 "--json", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "leave one session out: 3 folds" in printed
    assert "every one trained on (held out: the cross-validation above)" in printed
    document = json.loads(out.read_text())
    folds = document["cross_validation"]["folds"]
    assert [fold["label"] for fold in folds] == ["mon", "tue", "wed"]
    for fold in folds:
        assert {labels[row] for row in fold["rows"]} == {fold["label"]}
    assert document["validation"]["train_poses"] == 120


def test_a_rig_unknown_only_held_out_rows_touch_is_fitted_to_them(
        irb120: RobotModel, true_robot: RobotModel, port_m: np.ndarray) -> None:
    """A second port only the held-out rows read, 3 mm from where it was told: no training
    row moves its correction, so the held-out figures fit it to them first (the model is
    judged, not the start of a port the fit never saw)."""
    rng = np.random.default_rng(5)
    told = np.stack([port_m, port_m + np.array([0.3, 0.5, 0.0])])
    true = told + np.array([[0.0, 0.0, 0.0], [0.003, 0.0, 0.0]])
    q = random_poses(irb120, 80, rng)
    which = np.r_[np.zeros(60, dtype=np.intp), np.ones(20, dtype=np.intp)]
    lengths = np.linalg.norm(true_robot.flange_positions(q) - true[which], axis=1)
    data = length_measurements(q, lengths + rng.normal(0, 1e-5, 80), port=which)
    rig = Rig(told, ("a", "b"))
    settings = twin.CalibrationSettings(estimate=("port",))
    split = make_problem(irb120, data, rig=rig, settings=settings,
                         rows=(np.arange(60), np.arange(60, 80)))
    result = solve_many(irb120, split, ["lm"])["lm"]
    problem = split.problem
    plain = problem.model.residuals(result.x, problem.validation)
    assert np.sqrt(np.mean(plain**2)) > 1e-3
    assert result.metrics["validation"].rmse < 5e-5
    fitted = held_out_residuals(problem.model, result.x, problem.train, problem.validation)
    assert np.sqrt(np.mean(fitted**2)) == pytest.approx(result.metrics["validation"].rmse)


@pytest.mark.slow
def test_a_placement_held_out_is_judged_with_its_sockets_fitted_to_it() -> None:
    """Leave one placement of a ball bar out (the twin's fixed-points scenario, sockets 50 mm
    apart): the held-out sockets are touched in training only by their known distance, a row of
    no pose, so they are fitted to the held-out seatings first — the held-out RMSE is the
    seating noise (it was 28 mm when the distance counted as training them), and it is what the
    sockets' centres as the means of the predicted balls give (MUKCa's way, by hand)."""
    from twin.scenario import load_scenario
    from twin.sim import simulate

    sim = simulate(load_scenario(Path(__file__).resolve().parents[1] / "scenarios"
                                 / "fixed_points_irb120.toml"))
    data = sim.measurements
    placement = np.array([data.names("point")[j][:2] for j in data.index("point")])
    held, train = np.flatnonzero(placement == "f1"), np.flatnonzero(placement != "f1")
    settings = twin.CalibrationSettings(estimate=("attachment",))
    split = make_problem(sim.robot, data, rig=sim.rig_told, settings=settings,
                         rows=(train, held))
    result = solve_many(sim.robot, split, ["lm"])["lm"]
    model, held_data = split.problem.model, split.problem.validation
    residuals = held_out_residuals(model, result.x, split.problem.train, held_data)
    seatings = np.sqrt(np.mean(residuals[: 3 * len(held)] ** 2))
    assert seatings < 1.5e-5
    balls = model.positions(result.x, model.poses(held_data.q_rad))
    socket = held_data.index("point")
    by_hand = balls - np.stack([balls[socket == j].mean(axis=0) for j in socket])
    assert seatings == pytest.approx(np.sqrt(np.mean(by_hand**2)), rel=0.05)


@pytest.mark.parametrize(("flags", "message"), [
    (["--cv", "3", "--train-fraction", "0.5"], "--train-fraction: found --train-fraction with "
     "--cv"),
    (["--cv", "3", "--cv-by", "session"], "--cv: found --cv with --cv-by"),
    (["--cv", "1"], "--cv: found '1', expected an integer in 2..1000"),
    (["--cv", "500"], "--cv: found 500 folds of 120 poses, expected from 2 to 120 folds"),
    (["--cv-by", "session"], "found no column 'session'"),
    (["--cv", "3", "--method", "all"], "--cv: found --cv with --method all"),
])
def test_a_wrong_validation_flag_is_one_line(flags: list[str], message: str, csv_path: Path,
                                             refusals: object) -> None:
    """Each mistake: one line naming the flag, exit code 2, nothing written."""
    refusals.cli(["calibrate", csv_path, "--port", PORT, *flags], [csv_path],  # type: ignore
                 message)
