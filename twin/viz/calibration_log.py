"""Log a calibration run: scene, residuals, convergence, parameters and report.

Units: the 3D scene in m; residuals and RMSEs in mm, f in mm² (plots are read by people); the
bar charts in mm (δa, δd) and degrees (δα, δθ). The exact values under
``parameters/<source>/exact`` are float64 scalars in SI (m, rad), exactly the numbers of
``result.solver.x`` and of the truth, so they round-trip bit for bit; their ``names`` and
``units`` travel beside them.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np
import rerun as rr
from numpy.typing import ArrayLike, NDArray

from twin.calibration.result import CalibrationResult
from twin.dataset import Measurements
from twin.io.results import MM2_PER_M2
from twin.kinds import get_kind
from twin.model import Model
from twin.rig import Rig
from twin.robot import RobotModel
from twin.units import dh_rows_to_display, m_to_mm
from twin.unknowns import make_groups
from twin.viz import entities
from twin.viz.blueprint import calibration_blueprint
from twin.viz.recording_report import calibration_markdown
from twin.viz.scene import (
    NOMINAL_COLOR,
    TRUE_COLOR,
    log_measurement,
    log_robots,
    robot_color,
)
from twin.viz.writer import Writer

REJECTED_COLOR = (230, 30, 30)
"""Poses a robust loss rejected."""
BAR_GROUP_WIDTH = 0.8
"""Width of one joint's group of bars (the truth, then each method), in joint-index units."""


def bar_keys(table_is_length: ArrayLike) -> tuple[str, ...]:
    """The bar-chart rows of a table whose entries are lengths where ``table_is_length`` (4, n):
    a, d, alpha, theta, and beta when some joint is a Hayati joint."""
    lengths = np.asarray(table_is_length, dtype=bool)
    return tuple(key for key in entities.BAR_KEYS
                 if key != "beta" or not np.all(lengths[1]))


def _bar_rows(delta: NDArray[np.float64], table_is_length: ArrayLike
              ) -> dict[str, list[float]]:
    """Each bar row in its unit (mm, deg); d and β apart, 0 on joints without them."""
    lengths = np.asarray(table_is_length, dtype=bool)
    display = dh_rows_to_display(delta, lengths)
    second = np.asarray(display["d"])
    display["d"] = np.where(lengths[1], second, 0.0).tolist()
    display["beta"] = np.where(lengths[1], 0.0, second).tolist()
    return {key: display[key] for key in bar_keys(lengths)}


def log_parameters(
    writer: Writer, method: str | None, delta: NDArray[np.float64], values: NDArray[np.float64],
    names: tuple[str, ...], units: tuple[str, ...], color: tuple[int, int, int],
    slot: tuple[int, int] = (0, 1), table_is_length: ArrayLike | None = None,
) -> None:
    """One source's table errors as bars per row (mm, deg) and its values exactly (SI).

    Args:
        writer: Where to log.
        method: The method, or None for the truth.
        delta: Table errors, shape (4, n), m and rad.
        values: The exact values to keep, shape (p,), SI: the unknowns x of a method (table
            errors, then the joint-level and rig groups asked for) or the true table errors.
        names: Name of each value, shape (p,).
        units: The SI unit of each value (``m``, ``rad``, ``rad/(N·m)``), length p.
        color: Bar colour.
        slot: ``(index, count)``: this source's place among the sources drawn side by side in
            one chart, so that the truth and each method get their own bar per joint.
        table_is_length: Which table entries are lengths, (4, n); D-H's rows if None.
    """
    lengths = np.broadcast_to(np.array([True, True, False, False])[:, None], delta.shape) \
        if table_is_length is None else table_is_length
    display = _bar_rows(delta, lengths)
    index, count = slot
    width = BAR_GROUP_WIDTH / count
    abscissa = np.arange(1, delta.shape[1] + 1) - BAR_GROUP_WIDTH / 2 + (index + 0.5) * width
    for key in display:
        writer.once(entities.parameter_bars(method, key),
                    rr.BarChart(np.asarray(display[key]), abscissa=abscissa, color=color,
                                widths=np.full(abscissa.shape, width, dtype=np.float32)))
    writer.once(
        entities.parameter_exact(method),
        rr.Scalars(values),
        rr.AnyValues(names=list(names), units=list(units)),
    )


def pose_residuals(model: Model, x: ArrayLike, measurements: Measurements) -> NDArray[np.float64]:
    """One residual per pose, m: the signed row of a cable length, the length of the three rows
    of a tracker position or a fixed point (rows of known distances left out); shape (m,)."""
    rows = model.kind.rows_per_pose
    residuals = model.residuals(np.asarray(x, dtype=np.float64), measurements)
    per_pose = residuals[: rows * len(measurements)].reshape(len(measurements), rows)
    return per_pose[:, 0] if rows == 1 else np.linalg.norm(per_pose, axis=1)


def log_residuals_before(writer: Writer, model: Model, measurements: Measurements) -> None:
    """Per-pose residuals of the nominal model over all poses (``residuals/before``), mm."""
    before = pose_residuals(model, np.zeros(model.n_params), measurements)
    writer.once(entities.RESIDUALS_BEFORE, rr.SeriesPoints(colors=NOMINAL_COLOR, names="before"))
    writer.series(entities.RESIDUALS_BEFORE, entities.POSE_TIMELINE,
                  np.arange(len(measurements)), rr.Scalars.columns(scalars=m_to_mm(before)))


def log_residuals_after(
    writer: Writer, result: CalibrationResult, measurements: Measurements, order: int
) -> None:
    """Per-pose residuals of one method's model over all poses (``residuals/after/<m>``), mm,
    and the poses its robust loss rejected (``residuals/rejected/<m>``, red crosses)."""
    after = pose_residuals(result.model, result.solver.x, measurements)
    path = entities.residuals_after(result.method)
    writer.once(path, rr.SeriesPoints(colors=robot_color(result.method, order),
                                      names=f"after {result.method}"))
    writer.series(path, entities.POSE_TIMELINE, np.arange(len(measurements)),
                  rr.Scalars.columns(scalars=m_to_mm(after)))
    rejected = result.rejected_rows
    if rejected.size:
        path = entities.residuals_rejected(result.method)
        writer.once(path, rr.SeriesPoints(colors=REJECTED_COLOR, markers="cross",
                                          names=f"rejected by {result.method}"))
        writer.series(path, entities.POSE_TIMELINE, rejected,
                      rr.Scalars.columns(scalars=m_to_mm(after[rejected])))


def log_convergence(writer: Writer, method: str, result: CalibrationResult, order: int) -> None:
    """f [mm²] and train/validation RMSE [mm] per iteration, ``convergence/<method>/…``."""
    history = result.solver.history
    if not history:
        return
    iterations = np.array([record.iteration for record in history])
    series = dict(zip(entities.CONVERGENCE_QUANTITIES, (
        np.array([record.f_m2 for record in history]) * MM2_PER_M2,
        m_to_mm([record.train_rmse_m for record in history]),
        m_to_mm([record.validation_rmse_m for record in history]),
    ), strict=True))
    color = np.asarray(robot_color(method, order))
    lighter = (color + 255) // 2  # validation beside training in the same plot
    for quantity, values in series.items():
        path = entities.convergence(method, quantity)
        shade = lighter if quantity == "validation_rmse" else color
        writer.once(path, rr.SeriesLines(colors=shade.astype(np.uint8),
                                         names=f"{method} {quantity}"))
        writer.series(path, entities.ITERATION_TIMELINE, iterations,
                      rr.Scalars.columns(scalars=values))


class CalibrationLog:
    """Logs a calibration run as it goes: the setup at once, each method as it finishes
    (:meth:`add`, e.g. as the ``on_result`` of :func:`twin.calibration.pipeline.calibrate_many`),
    the report at the end (:meth:`finish`).

    Args:
        writer: Where to log.
        methods: The methods' names, in the order they will run.
        robot: The nominal robot.
        rig: The rig the calibration is told (ports, attachment, fixed points started).
        measurements: Every measured pose (train and validation).
        truth_delta: True D-H errors, shape (4, n), m and rad, if known.
    """

    def __init__(
        self,
        writer: Writer,
        methods: Sequence[str],
        robot: RobotModel,
        rig: Rig,
        measurements: Measurements,
        truth_delta: NDArray[np.float64] | None = None,
    ) -> None:
        if not methods:
            raise ValueError("methods: empty, expected at least one method")
        self.writer = writer
        self.methods = list(methods)
        self.measurements = measurements
        self.truth_delta = truth_delta
        self.rig = rig
        self.sources = len(self.methods) + (truth_delta is not None)
        nominal = Model(robot, rig, get_kind(measurements.kind), make_groups(["dh"], robot, rig))
        writer.stream.send_blueprint(calibration_blueprint(
            self.methods, truth_delta is not None, bar_keys(robot.is_length)))
        writer.once(entities.WORLD, rr.ViewCoordinates.RIGHT_HAND_Z_UP)
        robots = {"nominal": robot}
        if truth_delta is not None:
            robots["true"] = robot.perturbed(truth_delta)
            # The physical cable went to the true flange; without the truth it is drawn to the
            # first method's flange once that is known.
            self._log_cable(robots["true"])
            truth = np.asarray(truth_delta, dtype=np.float64)
            log_parameters(writer, None, truth, truth.ravel(), nominal.names, nominal.units,
                           TRUE_COLOR, (0, self.sources), robot.is_length)
        log_robots(writer, robots, measurements.q_rad)
        log_residuals_before(writer, nominal, measurements)

    def _log_cable(self, robot: RobotModel, rig: Rig | None = None) -> None:
        rig = rig or self.rig
        transforms = robot.flange_transforms(self.measurements.q_rad)
        points_m = transforms[:, :3, :3] @ rig.attachment_m + transforms[:, :3, 3]
        log_measurement(self.writer, rig, self.measurements, points_m)

    def add(self, result: CalibrationResult) -> None:
        """Log one method's identified robot, residuals, convergence and parameters."""
        order = self.methods.index(result.method)
        if order == 0 and self.truth_delta is None:
            self._log_cable(result.identified_geometry, replace(
                self.rig, ports_m=result.ports_m, attachment_m=result.attachment_m,
                points_m=result.points_m))
        log_robots(self.writer, {entities.identified_label(result.method):
                                 result.identified_geometry}, self.measurements.q_rad, order)
        log_residuals_after(self.writer, result, self.measurements, order)
        log_convergence(self.writer, result.method, result, order)
        log_parameters(self.writer, result.method, result.delta, result.solver.x,
                       result.model.names, result.model.units,
                       robot_color(result.method, order),
                       (order + (self.truth_delta is not None), self.sources),
                       result.robot.is_length)

    def finish(self, results: Mapping[str, CalibrationResult]) -> None:
        """Log the report: metrics of every method, flange error against the truth,
        identifiability."""
        self.writer.once(entities.REPORT, rr.TextDocument(
            calibration_markdown(results, self.measurements, self.truth_delta),
            media_type=rr.MediaType.MARKDOWN,
        ))


def log_calibration(
    writer: Writer,
    results: Mapping[str, CalibrationResult],
    measurements: Measurements,
    truth_delta: NDArray[np.float64] | None = None,
) -> None:
    """Everything about a finished calibration run (one or several methods on the same data).

    Args:
        writer: Where to log.
        results: Results by method name, as `calibrate_many` returns them.
        measurements: Every measured pose (train and validation).
        truth_delta: True D-H errors, shape (4, n), m and rad, if known.
    """
    if not results:
        raise ValueError("results: empty, expected at least one method")
    first = next(iter(results.values()))
    log = CalibrationLog(writer, list(results), first.robot, first.model.rig, measurements,
                         truth_delta)
    for result in results.values():
        log.add(result)
    log.finish(results)
