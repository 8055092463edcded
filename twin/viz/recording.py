"""A Rerun recording of a simulation, a calibration or a study: the façade commands log through.

:func:`open_recording` opens one on the sinks the options ask for (:mod:`twin.viz.sinks`: a
file, the native viewer, a web viewer); :class:`Recording` logs the scene, the calibration, the
convergence and the reports with the layout of :mod:`twin.viz.entities`.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import rerun as rr
from numpy.typing import NDArray

from twin.calibration.result import CalibrationResult
from twin.dataset import Measurements
from twin.rig import Rig
from twin.robot import RobotModel
from twin.viz import entities
from twin.viz.blueprint import scene_blueprint
from twin.viz.calibration_log import CalibrationLog, log_calibration
from twin.viz.options import RerunOptions
from twin.viz.scene import log_scene, robot_color
from twin.viz.sinks import open_sinks
from twin.viz.writer import Writer

APPLICATION_ID = "twin"


class Recording:
    """One open recording. Log through its methods; :func:`open_recording` closes it.

    Attributes:
        stream: The underlying ``rerun.RecordingStream``, for anything else.
        path: The ``.rrd`` file being written (final name), or None.
        url: The web viewer's address when serving, or None.
    """

    def __init__(self, stream: rr.RecordingStream, path: Path | None, url: str | None):
        self.stream = stream
        self.path = path
        self.url = url

    def log_calibration(
        self,
        results: Mapping[str, CalibrationResult] | CalibrationResult,
        measurements: Measurements,
        *,
        truth_delta: NDArray[np.float64] | None = None,
        times: Mapping[str, int] | None = None,
    ) -> None:
        """Scene, residuals, convergence, parameters and report of a calibration run.

        Args:
            results: Results by method name (or a single result).
            measurements: Every measured pose (train and validation).
            truth_delta: True D-H errors, shape (4, n), m and rad, if known.
            times: Extra sequence timelines stamped on every row, e.g. ``{"case": k}``.
        """
        if isinstance(results, CalibrationResult):
            results = {results.method: results}
        log_calibration(Writer(self.stream, times), results, measurements, truth_delta)

    def start_calibration(
        self,
        methods: Sequence[str],
        robot: RobotModel,
        rig: Rig,
        measurements: Measurements,
        *,
        truth_delta: NDArray[np.float64] | None = None,
    ) -> CalibrationLog:
        """Log a calibration's setup now and return the log its methods are added to as they
        finish (see :class:`twin.viz.calibration_log.CalibrationLog`)."""
        return CalibrationLog(Writer(self.stream), methods, robot, rig, measurements,
                              truth_delta)

    def log_scene(
        self,
        robots: Mapping[str, RobotModel],
        measurements: Measurements,
        rig: Rig,
        *,
        cable_to: str,
        times: Mapping[str, int] | None = None,
    ) -> None:
        """Robots in every pose and what was measured (see :func:`twin.viz.scene.log_scene`)."""
        self.stream.send_blueprint(scene_blueprint())
        log_scene(Writer(self.stream, times), robots, measurements, rig, cable_to)

    def log_histories(self, histories_mm: Mapping[str, Sequence[float]], trial: str) -> None:
        """One study trial's validation RMSE per iteration [mm] for each method, on the
        ``iteration`` timeline under ``convergence/<method>/trials/<trial>``, so the curves of
        all trials lie side by side in each method's plot."""
        writer = Writer(self.stream)
        for order, (method, values) in enumerate(histories_mm.items()):
            if not len(values):
                continue
            path = entities.trial_convergence(method, trial)
            writer.once(path, rr.SeriesLines(colors=robot_color(method, order),
                                             names=f"{method} {trial}"))
            writer.series(path, entities.ITERATION_TIMELINE, np.arange(len(values)),
                          rr.Scalars.columns(scalars=np.asarray(values, dtype=np.float64)))

    def log_report(self, markdown: str, path: str = entities.REPORT,
                   times: Mapping[str, int] | None = None) -> None:
        """A markdown document (the run's report by default)."""
        Writer(self.stream, times).once(path, rr.TextDocument(markdown,
                                                              media_type=rr.MediaType.MARKDOWN))


@contextmanager
def open_recording(
    options: RerunOptions, name: str, *, fallback_dir: Path | None = None
) -> Iterator[Recording]:
    """Open a recording on every sink the options ask for; close it on leaving the block.

    With ``options.serve`` the web viewer's URL is printed on opening, and leaving the block
    keeps serving until Ctrl-C. A viewer that cannot start is replaced by a file.

    Args:
        options: The sinks.
        name: The command (``"calibrate"``…): the recording's name and the fallback file's.
        fallback_dir: Folder of the fallback file (default: the current folder).
    """
    stream = rr.RecordingStream(APPLICATION_ID)
    with open_sinks(stream, options, name, fallback_dir) as opened:
        stream.send_recording_name(name)
        yield Recording(stream, opened.path, opened.url)
