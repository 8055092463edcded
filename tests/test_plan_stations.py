"""`twin plan` with named ports: poses and stations chosen together."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from twin.calibration.settings import CalibrationSettings
from twin.calibration.setup import make_model
from twin.cli import main
from twin.design.optimal import plan_stations
from twin.rig import Rig
from twin.robot import RobotModel, random_poses

STATIONS = ["front=600,-400,100", "left=300,600,50", "back=-500,-300,150"]


def test_stations_and_poses_are_planned_together(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """The plan names a station per pose, uses every station, and predicts a smaller flange
    error than as many random poses shared evenly between the stations."""
    out = tmp_path / "plan.csv"
    argv = ["plan", *(arg for station in STATIONS for arg in ("--port", station)),
            "--poses", "45", "--candidates", "300", "--estimate-port", "--joint-limits-only",
            "--out", str(out)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    rows = list(csv.DictReader(out.open()))
    assert len(rows) == 45 and {row["port"] for row in rows} == {"front", "left", "back"}
    planned = float(printed.split("planned")[1].split()[4])
    drawn = float(printed.split("random")[1].split()[4])
    assert planned < drawn, printed


def test_plan_stations_is_d_optimal_over_pairs(irb120: RobotModel) -> None:
    """The chosen (pose, station) pairs have a larger det(J_Bᵀ J_B) than random pairs from the
    same candidates, and the rows are those of the model measured from each pair's station."""
    rng = np.random.default_rng(5)
    ports = np.array([[0.6, -0.4, 0.1], [0.3, 0.6, 0.05], [-0.5, -0.3, 0.15]])
    candidates = np.stack([random_poses(irb120, 200, rng) for _ in ports])
    model = make_model(irb120, Rig(ports, ("front", "left", "back")),
                       settings=CalibrationSettings(estimate=('port',)))
    x0 = np.zeros(model.n_params)
    plan = plan_stations(model, x0, candidates, 45)
    np.testing.assert_array_equal(plan.q_rad, candidates[plan.port, plan.selection.rows % 200])
    rows = model.jacobian(x0, model.poses(plan.q_rad, port=plan.port))[1][:, plan.base_mask]
    assert np.linalg.slogdet(rows.T @ rows)[1] == pytest.approx(plan.selection.log_det)
    pick = rng.choice(600, 45, replace=False)
    q_all, port_all = candidates.reshape(600, -1), np.repeat(np.arange(3), 200)
    random_rows = model.jacobian(x0, model.poses(q_all[pick], port=port_all[pick]))[1]
    random_rows = random_rows[:, plan.base_mask]
    assert plan.selection.log_det > np.linalg.slogdet(random_rows.T @ random_rows)[1]
