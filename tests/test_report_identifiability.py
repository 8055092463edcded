"""The identifiability lines of the printed reports (one method and a comparison)."""

from __future__ import annotations

import numpy as np

from twin.calibration.pipeline import calibrate_many
from twin.dataset import Measurements
from twin.report.text import format_comparison, format_result
from twin.robot import RobotModel


def test_reports_name_the_unseen_directions_and_the_predicted_accuracy(
    irb120: RobotModel, measurements: Measurements, port_m: np.ndarray
) -> None:
    """Both reports give rank 19 of 24 and the named directions; each single report says they
    are held at the nominal and gives the noise estimate; the comparison lists each method's
    predicted flange error."""
    results = calibrate_many(irb120, measurements, port_m, ["lm", "lm-base"])
    single = format_result(results["lm-base"])
    assert "rank 19 of 24" in single and "d2-d3" in single
    assert "held at the nominal" in single and "noise estimate" in single
    assert "held at the nominal" in format_result(results["lm"])
    table = format_comparison(results)
    assert "rank 19 of 24" in table
    assert "predicted flange RMS error over the workspace [mm]: lm 0.0" in table
    assert ", lm-base 0.0" in table
    # Identifiability at the nominal geometry is computed once per run and shared.
    assert results["lm"].identifiability is results["lm-base"].identifiability
