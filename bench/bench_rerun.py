"""Cost of logging a calibration to Rerun, per pose and against the calibration itself.

Run by hand: ``python bench/bench_rerun.py``. For 120 and 1200 poses of an IRB 120 with a
known perturbation, times one LM calibration and the logging of its result (scene, residuals,
convergence, parameters, report) to an ``.rrd`` file, side by side in the same run, and prints
the logging time per pose and the ratio logging / calibration. Medians of repeated runs.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
from _timing import median_time, tiny_run

from twin.calibration.pipeline import calibrate_many
from twin.io.robot_file import default_robot
from twin.robot import random_poses
from twin.synthetic import synthesize
from twin.units import dh_rows_from_display, mm_to_m
from twin.viz.options import RerunOptions
from twin.viz.recording import open_recording

REPEATS = 5
PORT_M = mm_to_m([600.0, -400.0, 100.0])


def bench(n_poses: int, folder: Path, rng: np.random.Generator) -> str:
    """One table row: calibration and logging times for ``n_poses`` poses."""
    robot = default_robot()
    delta = dh_rows_from_display({"a": [0.5, -0.8, 0.6, 0.3, -0.4, 0.2],
                                  "d": [0.7, 0.4, -0.6, 0.5, 0.3, -0.5],
                                  "alpha": [0.1, -0.2, 0.15, -0.1, 0.2, 0.1],
                                  "theta": [0.2, 0.1, -0.15, 0.1, -0.2, 0.05]})
    q = random_poses(robot, n_poses, rng)
    data = synthesize(robot.perturbed(delta), q, PORT_M, float(mm_to_m(0.01)), rng)
    results = calibrate_many(robot, data, PORT_M, ["lm"], seed=0)
    path = folder / f"bench_{n_poses}.rrd"

    def log() -> None:
        with open_recording(RerunOptions(save=path), "bench") as recording:
            recording.log_calibration(results, data, truth_delta=delta)

    calibrate_s, _ = median_time(
        lambda: calibrate_many(robot, data, PORT_M, ["lm"], seed=0), REPEATS)
    log_s, _ = median_time(log, REPEATS)
    return (f"{n_poses:>6} {calibrate_s:>14.4f} {log_s:>9.4f} {log_s / n_poses * 1e6:>14.1f} "
            f"{log_s / calibrate_s:>14.2f} {path.stat().st_size / 1024:>11.0f}")


def main() -> None:
    global REPEATS
    tiny = tiny_run(__doc__)
    if tiny:
        REPEATS = 1
    rng = np.random.default_rng(1)
    print(f"{'poses':>6} {'calibrate [s]':>14} {'log [s]':>9} {'log/pose [µs]':>14} "
          f"{'log/calibrate':>14} {'file [KiB]':>11}")
    with tempfile.TemporaryDirectory(prefix="bench_rerun_") as folder:
        for n_poses in (40,) if tiny else (120, 1200):
            print(bench(n_poses, Path(folder), rng))


if __name__ == "__main__":
    main()
