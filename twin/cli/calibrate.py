"""`twin calibrate`: identify the robot's errors from a measurement file or a capture.

``--errors`` chooses the robot's error groups (D-H by default; transmission, backlash and
compliance beside it), or ``auto`` fits nested choices and keeps the one the data support
(:mod:`twin.calibration.selection`). The rig flags say how the data were measured
(docs/measurements.md).
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from twin.choices import DEFAULT_METHOD, DEFAULT_SCALE_SIGMAS, LOSSES, MAX_ITERATIONS, PROTOCOLS
from twin.cli.arguments import (
    AUTO_ERRORS,
    add_input_flags,
    add_limit_flags,
    add_output,
    add_seed,
    add_validation_flags,
    angles_deg,
    integer,
    method_name,
    share,
    sigma_mm,
    sigma_or_auto,
)
from twin.errors import InputError
from twin.solvers import SOLVERS, get_solver
from twin.unknowns import ERRORS
from twin.viz.options import add_rerun_flags

if TYPE_CHECKING:
    from pathlib import Path

    from twin.calibration.result import CalibrationResult
    from twin.cli.inputs import Inputs
    from twin.dataset import Measurements

NAME = "calibrate"
HELP = "identify the robot's errors from cable, tracker or fixed-point measurements"
DESCRIPTION = (
    "Identify the errors of a robot (and the rig's unknowns) from "
    "measurements. INPUT is a measurement CSV (q1..qN in degrees and one of: length in mm, "
    "with --port; x,y,z in mm from a laser tracker; point, the name of a fixed place) or a "
    "capture.toml written by `twin simulate` or `twin capture`. docs/measurements.md shows "
    "each rig."
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The subcommand's arguments."""
    add_input_flags(
        parser, input_help="MEASUREMENTS.csv (- for standard input) or capture.toml",
        errors_help="the robot's error groups to identify, comma-separated: "
        + ", ".join(ERRORS) + " (compliance or link_compliance; thermal needs a temperature_c "
        "column); or auto: fit dh, then add "
        "compliance, backlash, transmission one at a time, then all with link_compliance, and "
        "keep the lowest BIC (default: the capture's, else dh)", auto=True,
        tension_help="the cable's pull towards the port in newtons (the encoder's spring "
        "force; loads the joints for the compliance group); default: the capture's, else 0")
    parser.add_argument(
        "--method", default=DEFAULT_METHOD, type=method_name,
        help="method name or paper alias, or 'all': " + ", ".join(SOLVERS.choices()),
    )
    add_seed(parser, "seed of the split and of the method", default=0)
    parser.add_argument("--estimate-offset", action="store_true",
                        help="also identify an unknown cable-length offset")
    parser.add_argument("--estimate-scale", action="store_true",
                        help="also identify the encoder's scale error (a gain on every length, "
                        "shown in ppm; the port must then be told, not estimated, for the data "
                        "to see it)")
    parser.add_argument("--sigma", type=sigma_or_auto, metavar="MM|auto",
                        help="the instrument's noise 1σ in mm: the filters' measurement noise "
                        "and the misfit test's reference (default: the capture's [encoder] "
                        "sigma_mm with its resolution, else 0.01); auto: estimated from "
                        "repeat readings, else from the residuals of a first fit (said so)")
    parser.add_argument("--joint-resolution-deg", type=angles_deg, metavar="DEG[,DEG…]",
                        help="the resolution the joint angles were recorded to (one, or one "
                        "per joint): its rounding (r/√12) enters each row's variance through "
                        "the row's Jacobian, and the fit weights the rows by it (errors in "
                        "variables; default: the capture's)")
    parser.add_argument("--joint-sigma-deg", type=angles_deg, metavar="DEG[,DEG…]",
                        help="the noise 1σ of the recorded joint angles (one, or one per "
                        "joint), added to the resolution's: as --joint-resolution-deg")
    parser.add_argument("--repeatability", type=sigma_mm, metavar="MM",
                        help="the robot's RMS flange repeatability in mm: noise of every pose "
                        "that no model removes, added to --sigma (a length sees it over one "
                        "direction, r/√3); default: the capture's [encoder] repeatability_mm, "
                        "else 0")
    parser.add_argument("--loss", choices=LOSSES,
                        help="how residual rows count: linear (least squares, default) or a "
                        "robust loss that keeps a few gross errors from steering the fit; the "
                        "rows it rejects are listed (docs/measurements.md)")
    parser.add_argument("--loss-scale", type=sigma_mm, metavar="MM",
                        help=f"the robust loss's scale in mm (default {DEFAULT_SCALE_SIGMAS:g} "
                        "σ); rows beyond three scales count as rejected")
    parser.add_argument("--stop", choices=PROTOCOLS,
                        help="stopping protocol: 'converge' (default: stop on stated "
                        "convergence tests) or 'paper' (the paper's: f changes by less than "
                        "0.001 mm², 60 iterations, cascades 30 + 30); default: the capture's")
    parser.add_argument("--max-iterations", type=integer(1, MAX_ITERATIONS), metavar="N",
                        help="iteration limit of every method and cascade stage (default: the "
                        "protocol's, 200 to converge, 60 / 30 + 30 for the paper's)")
    parser.add_argument("--train-fraction", type=share, metavar="SHARE",
                        help="share of the poses used for identification, 1 for every pose "
                        "(default: the capture's, else 0.8)")
    add_validation_flags(parser)
    add_limit_flags(parser)
    add_output(parser, "OUT.json", "write the result as JSON", flag="--json", required=False)
    add_output(parser, "OUT.png", "draw the reference pose's readings against time (rows "
               "flagged reference; the drift test's figure)", flag="--drift-figure",
               required=False)
    add_rerun_flags(parser)


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    from twin.calibration.crossval import final_settings
    from twin.calibration.diagnosis import likely_causes
    from twin.calibration.pipeline import solve_many
    from twin.calibration.selection import warn_weak_data
    from twin.cli.inputs import make_split, resolve_inputs, truth_of
    from twin.cli.validation import cross_validation, validation_file
    from twin.io.measurements import load_measurements
    from twin.io.results import cross_validation_to_dict, result_to_dict, write_json
    from twin.io.truth import load_truth_delta
    from twin.report.text import format_comparison, format_cross_validation, format_result
    from twin.viz.commands import calibration_log

    inputs = resolve_inputs(args)
    robot, measurements_path = inputs.robot, inputs.measurements_path
    everything = args.method.strip().lower() == "all"
    methods = list(SOLVERS) if everything else [get_solver(args.method).name]
    measurements = load_measurements(measurements_path, robot, stdin=True)
    if args.drift_figure:
        _refuse_without_references(measurements, measurements_path)
    if args.errors == (AUTO_ERRORS,):
        if everything:
            raise InputError("--errors auto with --method all", "one method to compare the "
                             "error models with", source="--errors")
        return _run_auto(args, inputs, measurements)
    if args.cv or args.cv_by:  # the model reported is fitted on every pose
        inputs = inputs._replace(calibration=final_settings(inputs.calibration))
    split = make_split(inputs, measurements, args.seed, validation_file(args, inputs))
    warn_weak_data(robot, split, inputs.calibration.errors, measurements_path, args.seed)
    crossed = cross_validation(args, inputs, measurements, methods)
    truth = None
    if inputs.truth_path is not None and inputs.truth_path.exists():
        truth = load_truth_delta(inputs.truth_path, robot.n_joints, robot.is_length)
    fallback_dir = args.json.parent if args.json else None
    with calibration_log(args, methods, robot, split.problem.model.rig, measurements, truth,
                         fallback_dir=fallback_dir) as live:
        results = solve_many(robot, split, methods, seed=args.seed,
                             on_result=None if live is None else live.add)
        if len(results) == 1:
            (result,) = results.values()
            misfit = result.misfit is not None and result.misfit.misfit
            causes = likely_causes(split, result) if misfit else ()
            truth, errors = truth_of(inputs, result)
            if crossed is not None:
                print(format_cross_validation(crossed))
                print()
            print(format_result(result, truth, truth=errors, causes=causes,
                                cross_validated=crossed is not None))
            document = result_to_dict(result, causes=causes, truth=errors)
            if crossed is not None:
                document["cross_validation"] = cross_validation_to_dict(crossed)
        else:
            print(format_comparison(results))
            document = {"methods": {name: result_to_dict(r) for name, r in results.items()}}
        if args.json:
            write_json(args.json, document)
        if args.drift_figure:
            _draw_drift(args.drift_figure, next(iter(results.values())), measurements_path)
        if live is not None:
            live.finish(results)
    return 0


def _refuse_without_references(data: Measurements, source: object) -> None:
    """Refuse ``--drift-figure`` before any work for data with too few reference rows."""
    import numpy as np

    from twin.analysis.drift import MIN_READINGS
    from twin.dataset import REFERENCE

    flagged = int(np.sum(data.values[REFERENCE] > 0.5)) if REFERENCE in data.values else 0
    if flagged < MIN_READINGS:
        raise InputError(f"{flagged} row(s) flagged reference",
                         f"a reference column with {MIN_READINGS} or more rows at one pose "
                         "flagged 1", source="--drift-figure", where=str(source))


def _draw_drift(path: Path, result: CalibrationResult, source: object) -> None:
    """Write the drift test's figure; refuse data whose reference rows make no series."""
    from twin.analysis.drift import MIN_READINGS
    from twin.io.png import save_png
    from twin.report.plots import drift_figure

    if result.drift is None or not result.drift.series:
        raise InputError("no reference pose read at different times", f"one pose flagged "
                         f"reference {MIN_READINGS} or more times", source="--drift-figure",
                         where=str(source))
    save_png(drift_figure(result.drift, f"reference pose readings, {source}"), path)


def _run_auto(args: argparse.Namespace, inputs: Inputs, measurements: Measurements) -> int:
    """Fit the nested error models, print the comparison and the chosen one's result."""
    from twin.calibration.selection import choose_errors
    from twin.cli.inputs import refuse_inapplicable
    from twin.io.results import choice_to_dict, result_to_dict, write_json
    from twin.report.text import format_choice, format_result

    settings = inputs.calibration
    refuse_inapplicable(inputs, measurements)
    if len(inputs.rig.ports_m) != 1:
        raise InputError("--errors auto with this rig", "cable lengths from one port",
                         source="--errors")
    try:
        choice = choose_errors(
            inputs.robot, measurements, inputs.rig, method=get_solver(args.method).name,
            settings=settings, seed=args.seed)
    except InputError as exc:
        if exc.source is not None:
            raise
        raise InputError(exc.found, exc.expected, source=inputs.measurements_path) from None
    print(format_choice(choice))
    print()
    print(format_result(choice.best.result))
    if args.json:
        write_json(args.json, {**result_to_dict(choice.best.result),
                               "error_choice": choice_to_dict(choice)})
    return 0
