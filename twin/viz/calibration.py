"""Log a calibration run: scene, residuals, convergence, parameters and report.

Units: the 3D scene in m; residuals and RMSEs in mm, f in mm² (plots are read by people); the
bar charts in mm (δa, δd) and degrees (δα, δθ). The exact values under
``parameters/<source>/exact`` are float64 scalars in SI (m, rad), exactly the numbers of
``result.solver.x`` and of the truth, so they round-trip bit for bit; their ``names`` and
``units`` travel beside them.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import rerun as rr
from numpy.typing import ArrayLike, NDArray

from twin.cable import Measurements
from twin.calibration import CalibrationResult
from twin.io.results import MM2_PER_M2
from twin.robot import RobotModel
from twin.units import DH_KEYS, dh_rows_to_display, m_to_mm
from twin.viz import entities
from twin.viz.blueprint import calibration_blueprint
from twin.viz.report import calibration_markdown
from twin.viz.scene import NOMINAL_COLOR, TRUE_COLOR, log_scene, robot_color
from twin.viz.writer import Writer

BAR_GROUP_WIDTH = 0.8
"""Width of one joint's group of bars (the truth, then each method), in joint-index units."""


def log_parameters(
    writer: Writer, method: str | None, delta: NDArray[np.float64], values: NDArray[np.float64],
    names: tuple[str, ...], is_length: ArrayLike, color: tuple[int, int, int],
    slot: tuple[int, int] = (0, 1),
) -> None:
    """One source's D-H errors as bars per row (mm, deg) and its values exactly (SI).

    Args:
        writer: Where to log.
        method: The method, or None for the truth.
        delta: D-H errors, shape (4, n), m and rad.
        values: The exact values to keep, shape (p,), m and rad: the unknowns x of a method
            (D-H errors, then port and offset if estimated) or the true D-H errors.
        names: Name of each value, shape (p,).
        is_length: Which values are lengths (m) rather than angles (rad), shape (p,).
        color: Bar colour.
        slot: ``(index, count)``: this source's place among the sources drawn side by side in
            one chart, so that the truth and each method get their own bar per joint.
    """
    display = dh_rows_to_display(delta)
    index, count = slot
    width = BAR_GROUP_WIDTH / count
    abscissa = np.arange(1, delta.shape[1] + 1) - BAR_GROUP_WIDTH / 2 + (index + 0.5) * width
    for key in DH_KEYS:
        writer.once(entities.parameter_bars(method, key),
                    rr.BarChart(np.asarray(display[key]), abscissa=abscissa, color=color,
                                widths=np.full(abscissa.shape, width, dtype=np.float32)))
    writer.once(
        entities.parameter_exact(method),
        rr.Scalars(values),
        rr.AnyValues(names=list(names),
                     units=["m" if length else "rad" for length in np.asarray(is_length, bool)]),
    )


def log_residuals(
    writer: Writer, results: Mapping[str, CalibrationResult], measurements: Measurements
) -> None:
    """Per-pose residuals over all poses, nominal (``residuals/before``) and after each method.

    Residuals are in mm; each series says which poses were held out for validation.
    """
    first = next(iter(results.values()))
    poses = np.arange(len(measurements))
    before = first.model.residuals(np.zeros(first.model.n_params), measurements)
    writer.once(entities.RESIDUALS_BEFORE, rr.SeriesPoints(colors=NOMINAL_COLOR, names="before"))
    writer.series(entities.RESIDUALS_BEFORE, entities.POSE_TIMELINE, poses,
                  rr.Scalars.columns(scalars=m_to_mm(before)))
    for order, (name, result) in enumerate(results.items()):
        after = result.model.residuals(result.solver.x, measurements)
        path = entities.residuals_after(name)
        writer.once(path, rr.SeriesPoints(colors=robot_color(name, order), names=f"after {name}"))
        writer.series(path, entities.POSE_TIMELINE, poses,
                      rr.Scalars.columns(scalars=m_to_mm(after)))


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


def log_calibration(
    writer: Writer,
    results: Mapping[str, CalibrationResult],
    measurements: Measurements,
    truth_delta: NDArray[np.float64] | None = None,
) -> None:
    """Everything about one calibration run (one or several methods on the same data).

    Args:
        writer: Where to log.
        results: Results by method name, as `calibrate_many` returns them.
        measurements: Every measured pose (train and validation).
        truth_delta: True D-H errors, shape (4, n), m and rad, if known.
    """
    if not results:
        raise ValueError("results: empty, expected at least one method")
    methods = list(results)
    first = results[methods[0]]
    writer.stream.send_blueprint(calibration_blueprint(methods, truth_delta is not None))
    robots: dict[str, RobotModel] = {"nominal": first.robot}
    if truth_delta is not None:
        robots["true"] = first.robot.perturbed(truth_delta)
    robots.update({entities.identified_label(m): r.identified_robot for m, r in results.items()})
    cable_to = "true" if truth_delta is not None else entities.identified_label(methods[0])
    log_scene(writer, robots, measurements, first.model.port_m, cable_to)
    log_residuals(writer, results, measurements)
    has_truth = truth_delta is not None
    sources = len(results) + has_truth
    for order, (name, result) in enumerate(results.items()):
        log_convergence(writer, name, result, order)
        log_parameters(writer, name, result.delta, result.solver.x, result.model.names,
                       result.model.is_length, robot_color(name, order),
                       (order + has_truth, sources))
    if truth_delta is not None:
        truth = np.asarray(truth_delta, dtype=np.float64)
        n_dh = first.model.n_dh
        log_parameters(writer, None, truth, truth.ravel(), first.model.names[:n_dh],
                       first.model.is_length[:n_dh], TRUE_COLOR, (0, sources))
    writer.once(entities.REPORT, rr.TextDocument(
        calibration_markdown(results, measurements, truth_delta),
        media_type=rr.MediaType.MARKDOWN,
    ))
