"""Rerun recordings of the rigs beyond one cable: the rows a robust loss rejected, tracker
targets and fixed points, read back with Rerun's own reader."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tests.test_viz_rerun import column, read_rrd, scalars
from twin.cli import main
from twin.viz import entities

ROOT = Path(__file__).resolve().parents[1]


def test_rejected_rows_are_shown(tmp_path: Path) -> None:
    """The outliers regime under a Cauchy loss: the recording marks exactly the rows the JSON
    lists as rejected, at their residual."""
    out = tmp_path / "outliers"
    assert main(["simulate", str(ROOT / "scenarios" / "outliers_irb120.toml"), "--out",
                 str(out)]) == 0
    rrd, result = tmp_path / "calibrate.rrd", tmp_path / "result.json"
    assert main(["calibrate", str(out / "capture.toml"), "--rerun-save", str(rrd), "--json",
                 str(result)]) == 0
    rejected = json.loads(result.read_text())["rejected_rows"]
    truth = json.loads((out / "truth.json").read_text())["outlier_rows"]
    assert rejected == truth
    batches = read_rrd(rrd)
    path = entities.residuals_rejected("lm")
    poses = column(batches, path, entities.POSE_TIMELINE)
    assert [int(p) for p in poses] == rejected
    after = scalars(batches, entities.residuals_after("lm"))
    np.testing.assert_allclose(scalars(batches, path), after[rejected])
    assert np.all(np.abs(scalars(batches, path)) > 0.09)  # beyond 3 scales of 0.03 mm


@pytest.mark.slow
def test_tracker_and_fixed_points_draw_the_measured_points(tmp_path: Path) -> None:
    """Tracker targets and ball positions are drawn per pose under world/measured, one residual
    per pose (the length of its three rows), and the fixed points under world/fixed_points."""
    for name, fixed in (("tracker_irb120", False), ("fixed_points_irb120", True)):
        out = tmp_path / name
        assert main(["simulate", str(ROOT / "scenarios" / f"{name}.toml"), "--out",
                     str(out)]) == 0
        rrd = out / "calibrate.rrd"
        assert main(["calibrate", str(out / "capture.toml"), "--rerun-save", str(rrd)]) == 0
        batches = read_rrd(rrd)
        poses = len((out / "measurements.csv").read_text().splitlines()) - 1
        assert len(column(batches, entities.MEASURED, entities.POSE_TIMELINE)) == poses
        after = scalars(batches, entities.residuals_after("lm"))
        assert after.shape == (poses,) and np.all(after >= 0) and np.median(after) < 0.05
        assert (entities.FIXED_POINTS in batches) == fixed
