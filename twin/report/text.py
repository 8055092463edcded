"""Human-readable reports of calibration results (mm and degrees)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from twin.analysis.drift import MIN_READINGS, Drift
from twin.analysis.identifiability import WEAK_RTOL, Identifiability
from twin.analysis.metrics import Metrics
from twin.analysis.misfit import ALPHA
from twin.analysis.workspace import Workspace
from twin.calibration.crossval import CrossValidation
from twin.calibration.result import PRIOR_DECIDED, CalibrationResult
from twin.calibration.selection import ErrorChoice
from twin.dataset import Measurements
from twin.geometry.parametrisation import PARALLEL_THRESHOLD_DEG
from twin.geometry.rigid import angles
from twin.kinds import KINDS
from twin.loss import REJECT_SCALES
from twin.report.display import (
    JOINT_DECIMALS,
    LENGTH_DECIMALS,
    SIGNIFICANT,
    deg,
    deg_values,
    elapsed,
    in_unit,
    joint_level,
    mm,
    percent,
    plain,
    ppm,
    seconds,
    slot,
    xyz_mm,
)
from twin.rig import Rig
from twin.robot import RobotModel
from twin.solvers import SOLVERS, get_solver
from twin.units import DH_KEYS, slot_label

if TYPE_CHECKING:
    from twin.arrays import Array
    from twin.calibration.accuracy import TruthErrors
    from twin.calibration.diagnosis import Cause
    from twin.model import Model

MAX_ROWS_SHOWN = 20
"""Rejected rows listed in the report (the JSON lists them all)."""

MAE_NOTE = '* MAE = mean |r|, the metric the paper labels "STD"; std is the standard deviation.'


def _metric_row(label: str, m: Metrics) -> str:
    return f"  {label:<18}" + "".join(mm(v, width=10, unit=False)
                                      for v in (m.rmse, m.mae, m.std, m.max))


def _nominal_lines(nominal: Identifiability, beyond: str) -> list[str]:
    lines = [
        f"  identifiability (training poses, nominal geometry): rank {nominal.rank} of "
        f"{nominal.n_params}, condition {nominal.condition:.3g} "
        f"(tolerance {nominal.tolerance:g}, column-scaled Jacobian)",
        "  not identifiable: " + (", ".join(nominal.unidentifiable) or "none"),
    ]
    if nominal.beyond_points:
        lines.append(f"  {beyond} see what positions alone cannot: "
                     + ", ".join(nominal.beyond_points))
    return lines


def _held_lines(result: CalibrationResult) -> list[str]:
    """What was held at the nominal, what that cost, and a start kept instead of the answer."""
    held, unseen = result.held, result.unseen
    if held is None or unseen is None:
        return []
    lines = []
    if unseen.names:
        lines.append("  held at the nominal (not seen by these data: the minimum-norm solution "
                     "in the bound-scaled unknowns, so nothing unseen leaves the tool): "
                     + ", ".join(unseen.names)
                     + "; training objective "
                     + percent(held.cost_change, significant=3, sign=True))
    if held.kept_start:
        lines.append(f"  returned the start, not the method's point: {held.kept_start}")
    return lines


def _weak_lines(nominal: Identifiability, result: CalibrationResult) -> list[str]:
    """The combinations the training poses see only weakly, each with its σ from the noise
    estimate: those weak at the nominal geometry (in the unit of their leading unknown), and
    the nominal's null directions the identified geometry lets them see (in half-ranges of
    the search box)."""
    if result.uncertainty is None:
        return []
    noise = result.uncertainty.noise_sigma_m
    shown = []
    for name, leading, factor in zip(nominal.weak_names, nominal.weak_leading,
                                     nominal.weak_sigma_per_noise, strict=True):
        shown.append(f"{name} ±{in_unit(noise * factor, result.model.units[leading], 3)}")
    if result.unseen is not None:
        shown += [f"{name} ±{sigma:.2g} of its box" for name, sigma
                  in zip(result.unseen.weak_names, result.unseen.weak_sigma, strict=True)]
    return ["  weakly seen (σ from the noise estimate): " + ", ".join(shown)] if shown else []


def format_held(result: CalibrationResult) -> list[str]:
    """What was held at the nominal (and at what cost), and what the data see only weakly."""
    lines = _held_lines(result)
    if result.identifiability is not None:
        lines += _weak_lines(result.identifiability, result)
    return lines


def _accuracy_line(result: CalibrationResult) -> str:
    """The predicted accuracy, for the flange when the data pin it, else for the point they
    measure (an estimated attachment leaves the flange free to slide under it)."""
    assert result.uncertainty is not None
    uncertainty, gauge = result.uncertainty, result.gauge
    noise = f"  noise estimate {mm(uncertainty.noise_sigma_m)}; "
    if result.model.has("attachment"):
        return (noise + "predicted RMS error of the measured point (the attachment) over the "
                f"workspace {mm(uncertainty.point_rms_m)} (the flange is not "
                "pinned by these data: no flange figure)")
    modulo = f", modulo {gauge.describe()}" if gauge is not None and gauge.names else ""
    return (noise + "predicted flange RMS error over the workspace "
            f"{mm(uncertainty.flange_rms_m)}{modulo} (the identifiable "
            "combinations only)")


def format_identifiability(result: CalibrationResult) -> list[str]:
    """The identifiability and predicted-accuracy lines of one result (empty if not computed)."""
    nominal, identified = result.identifiability, result.identified_identifiability
    lines = []
    if nominal is not None:
        lines += _nominal_lines(nominal, result.model.kind.beyond_noun)
        lines += format_held(result)
    if identified is not None:
        lifted = " (the identified geometry lifts held directions off zero)" \
            if nominal is not None and identified.rank > nominal.rank else ""
        lines.append(
            f"  at the identified geometry: rank {identified.rank} of {identified.n_params}, "
            f"condition {identified.condition:.3g}, {identified.weak} weak "
            f"(singular value below {WEAK_RTOL:g} of the largest){lifted}"
        )
    if result.uncertainty is not None:
        lines.append(_accuracy_line(result))
    if result.workspace is not None:
        lines.append("  workspace: "
                     + result.workspace.describe(result.model.robot.prismatic))
    return lines


def format_stop(result: CalibrationResult) -> list[str]:
    """Why the method stopped (each stage of a cascade), and the unknowns left on a bound."""
    stages = result.solver.stages
    if len(stages) == 1:
        lines = [f"  stopped: {stages[0].stop_reason.describe(result.budget)}"]
    else:
        lines = [f"  stage {stage.method} ({stage.iterations} iterations): "
                 f"{stage.stop_reason.describe(result.budget)}" for stage in stages]
        if result.solver.converged and not result.solver.stop_reason.converged:
            lines.append(f"  the {stages[-1].method} stage found nothing better: the result is "
                         f"the converged {stages[0].method} point")
    held = result.at_bounds
    if held:
        lines.append("  at a bound of the search box: " + ", ".join(held)
                     + " (the truth may lie outside the box, or the data barely see it)")
    return lines + format_limits(result)


def format_limits(result: CalibrationResult) -> list[str]:
    """What the user said may move and how far (nothing when the defaults hold), and the
    unknowns a prior, not the data, decided."""
    settings, lines = result.settings, []
    rules = [(what, ", ".join(texts)) for what, texts in (
        ("search box", [rule.text for rule in settings.bounds]),
        ("priors (σ around the nominal)", [rule.text for rule in settings.priors]),
        ("fixed at the nominal", list(settings.fix))) if texts]
    if rules:
        lines.append("  " + "; ".join(f"{what}: {text}" for what, text in rules)
                     + " (the rest: each group's own box, the paper's ±5 mm / ±8° for the "
                     "D-H table)")
    decided = result.prior_decided
    if decided:
        lines.append(f"  decided by the prior, not the data (posterior σ above "
                     f"{PRIOR_DECIDED:.2f} of the prior's): " + ", ".join(decided))
    return lines


def format_parametrisation(robot: RobotModel) -> list[str]:
    """One line saying which joints are not standard D-H (none for a standard D-H arm): what
    the table's rows mean, and why a joint is Hayati."""
    kinds = robot.structure.parametrisation
    if set(kinds) == {"dh"}:
        return []
    hayati = [str(i + 1) for i, kind in enumerate(kinds) if kind == "hayati"]
    why = (f"; Hayati joint(s) {', '.join(hayati)}: the next axis within "
           f"{PARALLEL_THRESHOLD_DEG:g}° of parallel, beta (deg) in the d column") if hayati \
        else ""
    return [f"  joints 1..{len(kinds)}: " + ", ".join(kinds) + why]


def describe_rig(rig: Rig, measurements: Measurements) -> str:
    """``port (600.000, -400.000, 100.000) mm``, ``2 ports (front, left)``, ``tracker
    positions`` or ``6 fixed points`` (the kind's :meth:`~twin.kinds.base.Kind.describe`), with
    the attachment when it is off the flange."""
    text = KINDS.lookup(measurements.kind).describe(rig, measurements)
    if np.any(np.abs(rig.attachment_m) > 0):
        text += f", measured point {xyz_mm(rig.attachment_m)} in the flange frame"
    return text


def _scale_text(result: CalibrationResult) -> str:
    """``+98.7 ppm ± 3.1 ppm (1σ)``, or the value with why it has no σ (the data cannot see it:
    held at the start)."""
    sigma = np.nan if result.uncertainty is None else float(
        result.model.block(result.uncertainty.sigma, "scale")[0])
    if np.isfinite(sigma):
        return f"{ppm(result.scale)} ± {ppm(sigma, sign=False)} (1σ)"
    return (f"{ppm(result.scale)} (not identifiable from these data: held; a told port pins "
            "the scale, an estimated one trades with it)")


def format_rig(result: CalibrationResult) -> list[str]:
    """The rig's identified unknowns: ports, offset, attachment, tracker frame, fixed points."""
    model, lines = result.model, []
    if model.has("port"):
        rig = model.rig
        for j in rig.estimated_port_index:
            name = "" if len(rig.ports_m) == 1 else f" {rig.port_names[j]}"
            started = " (nobody measured it: started from the lengths by multilateration, " \
                f"at {xyz_mm(rig.ports_m[j])})" if rig.port_names[j] in rig.unknown_ports else ""
            lines.append(f"  identified port{name}: {xyz_mm(result.ports_m[j])}{started}")
    if model.has("offset") and model.rig.sessions:
        lines += [f"  identified length offset, session {name}: {mm(value)}"
                  for name, value in zip(model.rig.sessions, result.offsets_m, strict=True)]
    elif model.has("offset"):
        lines.append(f"  identified length offset: {mm(result.offset_m)}")
    if model.has("scale"):
        lines.append(f"  identified encoder scale: {_scale_text(result)}")
    if model.has("attachment"):
        lines.append(f"  identified attachment (flange frame): {xyz_mm(result.attachment_m)}")
    if model.has("base"):
        transform = result.base_in_tracker
        lines.append(f"  identified base in the tracker frame: {xyz_mm(transform[:3, 3])}, "
                     f"rx ry rz ({deg_values(angles(transform[:3, :3]))}) deg")
    if model.has("points"):
        lines.append(f"  identified fixed points: {len(model.rig.point_names)} (in the JSON)")
    lines += model.kind.report(model, result.solver.x)
    return lines


def format_noise(result: CalibrationResult) -> list[str]:
    """How each row's noise was taken: σ estimated from the data, and the joints' noise
    through each row's Jacobian (errors in variables); nothing when σ was stated and the joints
    exact."""
    lines = []
    if result.noise is not None:
        lines.append(f"  {result.noise.describe()}")
    if result.row_sigma is not None:
        joints = np.asarray(result.settings.joint_sigma_rad)
        shown = ", ".join(deg(value, significant=SIGNIFICANT, unit=False)
                          for value in np.unique(joints))
        low, middle, high = np.quantile(result.row_sigma, [0.0, 0.5, 1.0])
        lines.append(
            f"  errors in variables: each row weighted by 1/σ_i², σ_i² = σ² + g_iᵀ Σ_q g_i — "
            f"the reading's σ {mm(result.settings.sigma_m, significant=SIGNIFICANT)} (encoder "
            f"and repeatability) and the joints' {shown}° (1σ) through the row's Jacobian g_i: "
            f"σ_i from {mm(low, significant=SIGNIFICANT)} to {mm(high, significant=SIGNIFICANT)}"
            f" (median {mm(middle, significant=SIGNIFICANT)}); the misfit test uses the same "
            "variances")
    return lines


def format_fit(result: CalibrationResult, causes: Sequence[Cause] = ()) -> list[str]:
    """The misfit line, the rows the loss rejected, and what the data cannot see."""
    lines = []
    misfit = result.misfit
    if misfit is not None and misfit.misfit:
        likely = "; likely causes: " + ", ".join(cause.describe() for cause in causes) \
            if causes else ""
        stepped = f"; the residuals step at data row(s) {_step_rows(result)} (below)" \
            if result.steps else ""
        lines.append(f"  MISFIT: the model does not fit these data — training RMSE "
                     f"{mm(misfit.rmse_m, significant=SIGNIFICANT)} against a noise of "
                     f"{mm(misfit.noise_m, significant=SIGNIFICANT)} ({misfit.describe()}): "
                     f"{misfit.readings()}{likely}{stepped}")
    lines += format_steps(result)
    if result.drift is not None:
        lines += format_drift(result.drift)
    if result.loss.robust:
        rows = result.rejected_rows
        shown = ", ".join(str(row) for row in rows[:MAX_ROWS_SHOWN]) \
            + (", …" if rows.size > MAX_ROWS_SHOWN else "")
        lines.append(f"  {result.loss.name} loss, scale "
                     f"{mm(result.loss.scale_m, significant=SIGNIFICANT)}: {rows.size} row(s) "
                     f"rejected (beyond {REJECT_SCALES:g} scales; "
                     f"0-based data rows){': ' + shown if rows.size else ''}")
    gauge = result.gauge
    if gauge is not None and gauge.names:
        lines.append("  motions of the flange the data cannot see: " + gauge.describe()
                     + ("; pin them with " + " or ".join(gauge.pins) if gauge.pins else ""))
    return lines


def format_drift(drift: Drift) -> list[str]:
    """The drift test's line (:mod:`twin.analysis.drift`): the reference readings, how far
    the most drifting one moved and its spread, the test, and what a drift means."""
    if not drift.series:
        return [f"  drift: {drift.references} reference row(s), no reference pose read "
                f"{MIN_READINGS} times at different times: not tested"]
    worst = max(drift.series, key=lambda series: float(np.max(np.abs(series.z))))
    row = int(np.argmax(np.abs(worst.z)))
    readings = sum(series.rows.size for series in drift.series)
    span = max(float(np.ptp(series.time_s)) for series in drift.series)
    verdict = "DRIFT beyond the noise: the rig or the arm changed during the capture (a " \
        "warm-up: with a temperature_c per row, --errors thermal models it)" if drift.drift \
        else "no drift beyond the noise"
    return [f"  drift: {len(drift.series)} reference pose(s), {readings} readings over "
            f"{elapsed(span, drift.timed)}; the most drifting moved "
            f"{mm(worst.drift_m[row], significant=SIGNIFICANT, sign=True)} (spread "
            f"{mm(worst.spread_m, significant=SIGNIFICANT)}), slope z "
            f"{plain(drift.statistic, significant=3)} against "
            f"{plain(drift.threshold, significant=3)} (two-sided, p {plain(ALPHA)} over "
            f"{drift.tests} slope(s); noise {mm(drift.noise_m, significant=SIGNIFICANT)}, "
            f"{drift.noise_source}): {verdict}"]


def _step_rows(result: CalibrationResult) -> str:
    return ", ".join(str(step.row) for step in result.steps[:MAX_ROWS_SHOWN]) \
        + (", …" if len(result.steps) > MAX_ROWS_SHOWN else "")


def format_steps(result: CalibrationResult) -> list[str]:
    """The rows where the residuals jump by more than the noise allows
    (:mod:`twin.analysis.steps`), with what to do about it; nothing when none."""
    if not result.steps:
        return []
    jumps = ", ".join(f"row {step.row} by {mm(-step.size_m, sign=True)} (z {abs(step.z):.1f})"
                      for step in result.steps[:MAX_ROWS_SHOWN])
    remedy = "one encoder zero each is fitted already: the jump is within a session" \
        if len(result.model.rig.sessions) > 1 else "a session column (the label of each " \
        "row's session) gives each session its own encoder zero"
    return [f"  STEPS: the readings jump against the model at {len(result.steps)} place(s) "
            f"(0-based data rows, in the file's order; the level after less the level before, "
            f"in units of the noise as z): {jumps} — a "
            f"re-hooked cable, a re-zeroed encoder, a new session? {remedy}"]


def format_truth(truth: TruthErrors, point: bool = True,
                 workspace: Workspace | None = None) -> list[str]:
    """The errors against the truth over the workspace, raw and modulo the unseen motions; the
    measured point's line only if ``point`` (an attachment off the flange or estimated)."""
    lines = [f"  against the truth over the workspace{'' if workspace else ' poses'}: "
             f"flange RMS {mm(truth.flange_m)}"]
    if truth.motions:
        lines[-1] += f", {mm(truth.flange_gauge_free_m)} modulo " + ", ".join(truth.motions)
    if point:
        lines.append(f"  measured point RMS {mm(truth.point_m)}"
                     + (f", {mm(truth.point_gauge_free_m)} modulo "
                        + ", ".join(truth.point_motions) if truth.point_motions else ""))
    return lines


def has_point(result: CalibrationResult) -> bool:
    """Whether the measured point is not simply the flange centre (an attachment estimated, or
    told off the flange)."""
    return result.model.has("attachment") or bool(np.any(np.abs(result.model.rig.attachment_m)
                                                          > 0))


def format_result(result: CalibrationResult, truth_delta: NDArray[np.float64] | None = None,
                  *, truth: TruthErrors | None = None, causes: Sequence[Cause] = (),
                  cross_validated: bool = False) -> str:
    """Before/after metrics, run statistics and the identified D-H errors as a table.

    Args:
        result: The calibration.
        truth_delta: The true D-H errors, shape (4, n), m and rad, to print beside, if known.
        truth: The errors against the truth over the workspace, if known.
        causes: The likely causes of a misfit (:func:`twin.calibration.diagnosis.likely_causes`).
        cross_validated: Whether a cross-validation was printed above (the model fitted on
            every pose after it).
    """
    solver = get_solver(result.method)
    lines = [
        f"{result.robot.name} — {solver.name} ({solver.title}), seed {result.seed}, "
        + _poses_line(result, cross_validated),
        "  residuals [mm]          RMSE      MAE*       std       MAX",
        *_metric_rows(result),
        f"  {result.solver.iterations} iterations, {result.solver.evaluations} evaluations, "
        f"{seconds(result.solver.seconds)} ({result.budget.protocol} protocol)",
        *format_stop(result),
        "  " + MAE_NOTE,
        *format_identifiability(result),
    ]
    lines += format_rig(result)
    lines += format_noise(result)
    lines += format_fit(result, causes)
    if truth is not None:
        lines += format_truth(truth, has_point(result), result.workspace)
    is_length = result.robot.is_length
    header = "  joint"
    for key, lengths in zip(DH_KEYS, is_length, strict=True):
        label = f"δ{slot_label(key, lengths)}"
        header += f"{label:>{max(14, len(label) + 1)}}" \
            + (f"{'true':>10}" if truth_delta is not None else "")
    kinds = set(result.robot.structure.parametrisation)
    errors = "D-H" if kinds == {"dh"} else "/".join(sorted(kinds))
    lines += ["", f"Identified {errors} errors"
              + (" (and the truth)" if truth_delta is not None else ""),
              *format_parametrisation(result.robot), header]
    held = _held_entries(result)
    for i in range(result.robot.n_joints):
        row = f"  {i + 1:>5}"
        for k, (key, lengths) in enumerate(zip(DH_KEYS, is_length, strict=True)):
            row += slot(result.delta[k, i], lengths[i],
                        width=max(14, len(slot_label(key, lengths)) + 2) - 1)
            row += HELD_MARK if held[k, i] else " "
            if truth_delta is not None:
                row += slot(truth_delta[k, i], lengths[i], width=10)
        lines.append(row)
    if held.any():
        lines.append(f"  {HELD_MARK} seen only in a combination, or not at all: the value is "
                     "the hold's minimum-norm split of what the data saw, not a measurement")
    lines += format_joint_groups(result)
    lines += format_thermal(result)
    return "\n".join(lines)


HELD_MARK = "~"
"""Marks a table entry the data saw only in a combination, or not at all."""


def _held_entries(result: CalibrationResult) -> NDArray[np.bool_]:
    """Which entries of the table, shape (4, n), lie in a held direction
    (:meth:`twin.analysis.unseen.Unseen.held`)."""
    n = result.robot.n_joints
    held = result.unseen.held(result.model.names) if result.unseen is not None else frozenset()
    names = result.robot.structure.parameter_names
    return np.array([name in held for name in names], dtype=bool).reshape(4, n)


def _poses_line(result: CalibrationResult, cross_validated: bool) -> str:
    """How many poses trained and where the validation poses come from."""
    trained = result.train_rows.size
    if cross_validated and not result.held_out:
        return f"{trained} poses, every one trained on (held out: the cross-validation above)"
    if result.held_out:
        shown = result.metrics.get("validation")
        return f"{trained} train poses, validated on {result.held_out}" + (
            "" if shown is not None else " (no poses)")
    if not result.validated:
        share = result.settings.train_fraction
        rounded = f"; a training share of {share:g} rounds to every pose" if share < 1 else ""
        return (f"{trained} poses, every one trained on (no validation poses{rounded}: "
                "--validate FILE or --cv K for held-out figures)")
    return f"{trained} train / {result.validation_rows.size} validation poses"


def _metric_rows(result: CalibrationResult) -> list[str]:
    """Before and after, on the validation poses when there are some; the start on the
    training poses, labelled so, when there are none."""
    if not result.validated:
        return [_metric_row("before (train)", result.metrics["before"]),
                _metric_row("after, train", result.metrics["train"])]
    return [_metric_row("before (valid.)", result.metrics["before"]),
            _metric_row("after, train", result.metrics["train"]),
            _metric_row("after, validation", result.metrics["validation"])]


JOINT_GROUP_COLUMNS: dict[str, tuple[str, ...]] = {
    "transmission": ("sin q", "cos q", "sin 2q", "cos 2q"), "backlash": ("backlash",),
    "compliance": ("compliance",)}
"""Columns of each joint-level group in the report, one row per revolute joint."""
SLIDE_GROUP_COLUMNS: dict[str, tuple[str, ...]] = {
    "transmission": ("scale",), "backlash": ("lost motion",), "compliance": ("compliance",)}
"""The same for a prismatic joint (:mod:`twin.unknowns.transmission` and the others)."""


def format_joint_groups(result: CalibrationResult) -> list[str]:
    """The identified joint-level errors, one row per joint, each with its σ (— where the
    poses do not identify it); the prismatic joints in a table of their own (a scale in µm/m,
    a lost motion in mm, a compliance in µm/N); empty without joint-level groups."""
    model = result.model
    present = [name for name in JOINT_GROUP_COLUMNS if model.has(name)]
    if not present:
        return []
    sigma = result.uncertainty.sigma if result.uncertainty is not None \
        else np.full(model.n_params, np.nan)
    sliding = model.robot.prismatic
    lines = []
    for title, columns, joints in (
            ("Identified joint-level errors", JOINT_GROUP_COLUMNS, np.flatnonzero(~sliding)),
            ("Identified joint-level errors of the prismatic joints", SLIDE_GROUP_COLUMNS,
             np.flatnonzero(sliding))):
        if joints.size:
            lines += ["", title, *_joint_table(model, result.solver.x, sigma, present, columns,
                                               joints)]
    return lines


def format_thermal(result: CalibrationResult) -> list[str]:
    """The identified growth of each link per kelvin (µm/K), one row per joint, each with its
    σ (— where the data do not see it, — for an entry that does not grow), and the reference
    temperature the D-H lengths hold at; empty without thermal unknowns."""
    model = result.model
    if not model.has("thermal") or model.rig.temperature_ref_c is None:
        return []
    group, where = model.group("thermal"), model.slice("thermal")
    sigma = result.uncertainty.sigma[where] if result.uncertainty is not None \
        else np.full(group.size, np.nan)
    values, label = joint_level(result.solver.x[where], group.units[0])
    deviations, _ = joint_level(sigma, group.units[0])
    found = dict(zip(group.names, zip(values, deviations, strict=True), strict=True))
    held = result.unseen.held(model.names) if result.unseen is not None else frozenset()
    lines = ["", f"Identified thermal growth (the D-H lengths are the links' at "
             f"{plain(model.rig.temperature_ref_c, 2)} °C, the data's mean temperature)",
             "  joint" + "".join(f"{f'{slot} [{label}]':>16} {'±σ':>8}"
                                 for slot in ("k_a", "k_d"))]
    for i, slots in enumerate(model.robot.structure.slot_names):
        row = f"  {i + 1:>5}"
        for name in slots[:2]:
            key = f"k_{name}{i + 1}"
            value, deviation = found.get(key, (np.nan, np.nan))
            row += (plain(value, JOINT_DECIMALS, width=16) if np.isfinite(value)
                    else f"{'—':>16}") + (HELD_MARK if key in held else " ")
            row += plain(deviation, JOINT_DECIMALS, width=8) if np.isfinite(deviation) \
                else f"{'—':>8}"
        lines.append(row)
    if held & set(group.names):
        lines.append(f"  {HELD_MARK} seen only in a combination, or not at all (held at the "
                     "hold's minimum-norm split)")
    return lines


def _joint_table(model: Model, x: Array, sigma: Array, present: list[str],
                 columns: dict[str, tuple[str, ...]], joints: NDArray[np.intp]) -> list[str]:
    """The header and one row per joint of ``joints`` of the groups ``present``."""
    header, rows = "  joint", [f"  {i + 1:>5}" for i in joints]
    for name in present:
        group, where = model.group(name), model.slice(name)
        owner = np.asarray(group.joint)
        label = ""
        for row, i in enumerate(joints):
            mine = np.flatnonzero(owner == i)
            unit = group.units[mine[0]]
            values, label = joint_level(x[where][mine], unit)
            deviations, _ = joint_level(sigma[where][mine], unit)
            decimals = LENGTH_DECIMALS if unit == "m" else JOINT_DECIMALS
            for value, deviation in zip(values, deviations, strict=True):
                rows[row] += plain(value, decimals, width=24) + (
                    plain(deviation, decimals, width=8) if np.isfinite(deviation)
                    else f"{'—':>8}")
        header += "".join(f"{f'{column} [{label}]':>24}{'±σ':>8}" for column in columns[name])
    return [header, *rows]


def format_cross_validation(crossed: CrossValidation) -> str:
    """Each fold's held-out residuals against the nominal's, the pooled figures of every
    held-out row, and the RMSE over the folds (mean, RMS, spread)."""
    solver = get_solver(crossed.method)
    rows = sum(fold.rows.size for fold in crossed.folds)
    width = max(12, *(len(fold.label) + 2 for fold in crossed.folds))
    lines = [f"Cross-validation — {solver.name}, {crossed.how}: {len(crossed.folds)} folds, "
             f"each of the {rows} poses held out once",
             f"  {'held out':<{width}}{'poses':>6}{'before RMSE':>13}{'RMSE':>10}{'MAE*':>10}"
             f"{'MAX':>10}{'train RMSE':>12}  [mm]"]
    for fold in crossed.folds:
        lines.append(f"  {fold.label:<{width}}{fold.rows.size:>6}"
                     + mm(fold.before.rmse, width=13, unit=False)
                     + "".join(mm(value, width=10, unit=False) for value in
                               (fold.held_out.rmse, fold.held_out.mae, fold.held_out.max))
                     + mm(fold.train.rmse, width=12, unit=False))
    pooled = crossed.pooled
    lines.append(f"  {'pooled':<{width}}{rows:>6}" + mm(crossed.pooled_before.rmse, width=13,
                                                           unit=False)
                 + "".join(mm(value, width=10, unit=False)
                           for value in (pooled.rmse, pooled.mae, pooled.max)))
    mean, rms, spread = crossed.rmse_over_folds()
    lines.append(f"  held-out RMSE over the folds: mean {mm(mean)}, RMS {mm(rms)}, std "
                 f"{mm(spread)}; the model below is fitted on every pose")
    return "\n".join(lines)


def format_choice(choice: ErrorChoice) -> str:
    """The ``--errors auto`` table: each nested error model's unknowns, rank, residuals and
    BIC, the chosen one marked, and the rule."""
    names = ["+".join(candidate.errors) for candidate in choice.candidates]
    width = max([44, *(len(name) + 1 for name in names)])
    lines = ["Error models, fitted on the same training poses "
             f"({choice.best.result.method}):",
             f"  {'errors':<{width}}{'unknowns':>9}{'rank':>6}{'train RMSE':>12}"
             f"{'valid. RMSE':>13}{'BIC':>12}  [mm]"]
    for k, candidate in enumerate(choice.candidates):
        train = mm(candidate.result.metrics["train"].rmse, width=12, unit=False)
        validation = mm(candidate.result.metrics["validation"].rmse, width=13, unit=False) \
            if candidate.result.validated else f"{'—':>13}"
        mark = "  <- chosen" if k == choice.chosen else ""
        lines.append(f"  {names[k]:<{width}}{candidate.unknowns:>9}"
                     f"{candidate.rank:>6}{train}{validation}"
                     f"{candidate.bic:>12.1f}{mark}")
    lines += [f"  skipped: {reason}" for reason in choice.skipped]
    lines += ["  rule: the lowest BIC = m ln(RSS/m) + k ln m (m training residuals, k the rank:",
              "  each identified unknown costs ln m); the validation RMSE is shown as a check"]
    return "\n".join(lines)


def format_comparison(results: Mapping[str, CalibrationResult]) -> str:
    """A table like the paper's Table 6: validation metrics and time per method."""
    first = next(iter(results.values()))
    shown = "validation" if first.validated else "train"
    lines = [
        f"  {first.budget.protocol} protocol; "
        + ("validation residuals" if first.validated else
           "training residuals (no validation poses: every pose trained on)"),
        "  method      paper    RMSE     MAE*      std      MAX [mm]   time [s]   iter    evals"
        "  stopped by",
    ]
    lines.append(f"  {'before':<10}  {'':<5}"
                 + "".join(mm(v, width=9, unit=False) for v in first.metrics["before"]))
    for name, result in results.items():
        alias = SOLVERS.alias(name).upper()
        lines.append(
            f"  {name:<10}  {alias:<5}"
            + "".join(mm(v, width=9, unit=False) for v in result.metrics[shown])
            + f"{result.solver.seconds:>11.3f}{result.solver.iterations:>7}"
            f"{result.solver.evaluations:>9}  {result.solver.stop_label}"
        )
    lines.append("  " + MAE_NOTE)
    if first.identifiability is not None:
        lines += _nominal_lines(first.identifiability, first.model.kind.beyond_noun)
        lines += _held_lines(first)[:1]
    kept = [name for name, result in results.items()
            if result.held is not None and result.held.kept_start]
    if kept:
        lines.append(f"  returned their start (no better than it on the training poses, by BIC): "
                     f"{', '.join(kept)}")
    point = first.model.has("attachment")
    predicted = [
        f"{name} {mm(u.point_rms_m if point else u.flange_rms_m, unit=False)}"
        for name, u in ((name, result.uncertainty) for name, result in results.items())
        if u is not None
    ]
    if predicted:
        what = "measured point (the flange is not pinned)" if point else "flange"
        lines.append(f"  predicted {what} RMS error over the workspace [mm]: "
                     + ", ".join(predicted))
        if first.workspace is not None:
            lines.append("  workspace: "
                         + first.workspace.describe(first.model.robot.prismatic))
    misfits = [name for name, result in results.items()
               if result.misfit is not None and result.misfit.misfit]
    if misfits:
        lines.append(f"  MISFIT: {', '.join(misfits)} do(es) not fit these data (chi-square of "
                     f"the training residuals above its {1 - ALPHA:g} quantile): calibrate with "
                     "one method for the likely causes")
    if first.loss.robust:
        lines.append(f"  rows rejected by the {first.loss.name} loss (scale "
                     f"{mm(first.loss.scale_m, significant=SIGNIFICANT)}): " + ", ".join(
                         f"{name} {result.rejected_rows.size}" for name, result in results.items())
                     + " (the JSON lists them)")
    if first.gauge is not None and first.gauge.names:
        lines.append("  motions of the flange the data cannot see: " + first.gauge.describe())
    return "\n".join(lines)
