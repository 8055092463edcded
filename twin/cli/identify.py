"""`twin identify`: what a measurement set identifies, how well, and where the flange is best."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from twin.choices import DEFAULT_METHOD
from twin.cli.arguments import add_input_flags, add_output, add_seed, method_name, sigma_mm
from twin.unknowns import ERRORS

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from twin.analysis.identifiability import Identifiability
    from twin.calibration.accuracy import TruthErrors
    from twin.calibration.assessment import Assessment
    from twin.calibration.result import CalibrationResult
    from twin.cli.inputs import Inputs
    from twin.model import Model

NAME = "identify"
HELP = "report what a measurement set identifies, and how well"
DESCRIPTION = (
    "Identifiability of a measurement set: rank, condition number and the "
    "unidentifiable combinations of the D-H errors at the nominal geometry, observability "
    "indices and the Cramér–Rao bound on the flange position (on the measured point when the "
    "data do not pin the flange); then a calibration with --method (the default of twin "
    "calibrate, so both state the same fit and noise estimate) and the same at the identified "
    "geometry, with per-parameter standard deviations."
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The subcommand's arguments."""
    add_input_flags(
        parser, input_help="MEASUREMENTS.csv (needs --port; - for standard input) or "
        "capture.toml", errors_help="the robot's error groups, comma-separated: "
        + ", ".join(ERRORS) + " (default: the capture's, else dh)",
        tension_help="the cable's pull in N, for the compliance group (default: the capture's, "
        "else 0)")
    parser.add_argument("--method", default=DEFAULT_METHOD, type=method_name,
                        help=f"the calibration method (default: {DEFAULT_METHOD}, as twin "
                        "calibrate's)")
    parser.add_argument("--estimate-offset", action="store_true",
                        help="treat the cable-length offset as unknown too")
    parser.add_argument("--estimate-scale", action="store_true",
                        help="treat the encoder's scale (a gain on every length, ppm) as "
                        "unknown too")
    parser.add_argument("--sigma", type=sigma_mm, metavar="MM",
                        help="the instrument's noise 1σ in mm, for the Cramér–Rao bound and the "
                        "misfit test (default: the capture's [encoder] sigma_mm with its "
                        "resolution, else 0.01)")
    add_seed(parser, "seed of the split, of the calibration and of the workspace poses",
             default=0)
    add_output(parser, "OUT.png", "write a map of the predicted flange error over joints 2 and 3",
               flag="--map", required=False)
    add_output(parser, "OUT.json", "write the report as JSON", flag="--json", required=False)


def _identifiability_lines(ident: Identifiability) -> list[str]:
    from twin.analysis.identifiability import WEAK_RTOL

    lines = [
        f"  rank {ident.rank} of {ident.n_params} (singular values of the column-scaled "
        f"Jacobian below {ident.tolerance:g} of the largest count as zero), "
        f"condition {ident.condition:.3g}",
    ]
    if ident.weak:
        lines.append(f"  {ident.weak} identified direction(s) weak: singular value below "
                     f"{WEAK_RTOL:g} of the largest")
    lines.append("  not identifiable: " + (", ".join(ident.unidentifiable) or "none"))
    return lines


def _sigma_table(model: Model, sigma: NDArray[np.float64]) -> list[str]:
    """Per-parameter 1σ in mm and degrees; '—' for the dependent (not identifiable) ones."""
    import numpy as np

    from twin.report.display import SIGMA_DECIMALS, slot
    from twin.units import DH_KEYS, slot_label

    shape = model.robot.dh.shape
    is_length = model.robot.is_length
    table = model.group("dh").spread(model.block(sigma, "dh")).reshape(shape)
    labels = [f"σ {slot_label(key, lengths)}" for key, lengths in zip(DH_KEYS, is_length,
                                                                       strict=True)]
    width = max(16, *(len(label) + 1 for label in labels))
    header = "  joint" + "".join(f"{label:>{width}}" for label in labels)
    lines = [header]
    for i in range(shape[1]):
        row = "".join(
            f"{'—':>{width}}" if np.isnan(table[k, i])
            else slot(table[k, i], is_length[k, i], SIGMA_DECIMALS, width=width)
            for k in range(len(DH_KEYS))
        )
        lines.append(f"  {i + 1:>5}{row}")
    return lines


def _one_method(text: str) -> str:
    """The method's registry name; ``all`` is refused (an assessment runs one calibration)."""
    from twin.errors import InputError
    from twin.solvers import SOLVERS, get_solver

    if text.strip().lower() == "all":
        raise InputError("'all'", "one method: " + ", ".join(SOLVERS.choices()),
                         where="--method")
    return get_solver(text).name


def _truth(inputs: Inputs, result: CalibrationResult) -> tuple[TruthErrors | None, list[str]]:
    """The errors against the capture's truth file, if it has one, and their report lines."""
    from twin.cli.inputs import truth_of
    from twin.report.display import mm
    from twin.report.text import format_truth, has_point

    _, truth = truth_of(inputs, result)
    if truth is None or inputs.truth_path is None:
        return truth, []
    lines = [f"  true flange RMS error over the workspace {mm(truth.flange_m)} (against the "
             f"D-H table of {inputs.truth_path.name})"]
    point = format_truth(truth, has_point(result))[1:]
    lines += point if not truth.motions else [
        f"    modulo {', '.join(truth.motions)}: {mm(truth.flange_gauge_free_m)}", *point]
    return truth, lines


def _bound_line(assessment: Assessment, sigma_m: float) -> str:
    """The Cramér–Rao bound over the workspace: of the flange, or of the measured point when
    the data do not pin the flange."""
    from twin.report.display import SIGNIFICANT, mm

    where = f"at σ = {mm(sigma_m, significant=SIGNIFICANT)}: "
    if assessment.pinned:
        return (f"  Cramér–Rao bound {where}flange RMS error over the workspace "
                f"{mm(assessment.score.flange_rms_m)}")
    assert assessment.point_bound_m is not None
    return (f"  Cramér–Rao bound {where}RMS error of the measured point over the workspace "
            f"{mm(assessment.point_bound_m)} (the flange is not pinned by these data: no "
            "flange figure)")


def _held_out_rmse(result: CalibrationResult) -> str:
    """``validation RMSE 0.0125 mm``, or the training RMSE when every pose trained."""
    from twin.report.display import mm

    scored = "validation" if result.validated else "train"
    return f"{scored} RMSE {mm(result.metrics[scored].rmse)}"


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    from twin.calibration.assessment import assess, flange_error_map
    from twin.cli.inputs import make_split, resolve_inputs
    from twin.io.measurements import load_measurements
    from twin.io.png import save_png
    from twin.io.results import assessment_to_dict, write_json
    from twin.report.display import mm
    from twin.report.plots import accuracy_map
    from twin.report.text import (
        describe_rig,
        format_fit,
        format_held,
        format_joint_groups,
        format_thermal,
    )
    from twin.units import m_to_mm

    inputs = resolve_inputs(args)
    robot, measurements_path = inputs.robot, inputs.measurements_path
    data = load_measurements(measurements_path, robot, stdin=True)
    split = make_split(inputs, data, args.seed)
    method = _one_method(args.method)
    assessment = assess(robot, split, data, seed=args.seed, method=method)
    data, nominal, score, result = assessment[:4]
    model = split.problem.model
    indices = score.observability
    lines = [
        f"{robot.name} — {len(data)} poses from {measurements_path}, "
        f"{describe_rig(model.rig, data)}, {model.n_params} unknowns ("
        + ", ".join(f"{group.name} {group.size}" for group in model.groups) + ")",
        "At the nominal geometry (all poses):",
        *_identifiability_lines(nominal),
        "    (coefficients in column-scaled units: each unknown in units of its column norm)",
        f"  base parameters ({nominal.rank}): " + ", ".join(nominal.base_names),
        f"  observability (base columns, SI): O1 {indices.o1:.4g}  O3 {indices.o3:.4g}  "
        f"O4 {indices.o4:.4g}  condition {indices.condition:.4g}",
        _bound_line(assessment, inputs.calibration.sigma_m),
        f"  workspace: {assessment.workspace.describe(robot.prismatic)}",
    ]
    assert result.identified_identifiability is not None and result.uncertainty is not None
    uncertainty = result.uncertainty
    lines += [
        f"At the identified geometry ({method}, seed {args.seed}, "
        f"{result.train_rows.size} training poses):",
        f"  {_held_out_rmse(result)}, noise estimate {mm(uncertainty.noise_sigma_m)}",
        *_identifiability_lines(result.identified_identifiability),
        "  predicted " + (f"flange RMS error over the workspace {mm(uncertainty.flange_rms_m)}"
                          if assessment.pinned else
                          "RMS error of the measured point over the workspace "
                          f"{mm(uncertainty.point_rms_m)}") + " (from the noise estimate)",
        *format_held(result),
        *format_fit(result),
        *format_joint_groups(result),
        *format_thermal(result),
    ]
    truth, truth_lines = _truth(inputs, result)
    lines += [
        *truth_lines,
        "  standard deviations of the unknowns as returned, held at the nominal along what the "
        "data cannot see (held entirely: —)",
        *_sigma_table(model, uncertainty.sigma),
    ]
    print("\n".join(lines))
    if args.map:
        what = "flange" if assessment.pinned else "measured point"
        save_png(accuracy_map(*flange_error_map(result.model, result.solver.x,
                                                uncertainty.covariance, assessment.workspace,
                                                measured=not assessment.pinned),
                              f"{robot.name}: predicted {what} error after {method}, "
                              f"{len(data)} poses (the other joints mid-range)"), args.map)
        print(f"map: {args.map}")
    if args.json:
        write_json(args.json, assessment_to_dict(
            assessment, float(m_to_mm(inputs.calibration.sigma_m)), truth))
    return 0
