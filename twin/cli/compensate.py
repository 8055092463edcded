"""`twin compensate`: joint angles that make the identified robot go where it should.

With ``--targets`` (flange positions x,y,z in mm) or ``--joints`` (a program q1..q6 in degrees,
written against the nominal model) it writes corrected joint angles with a per-row status; with
``--verify SCENARIO.toml`` it measures, in the MuJoCo twin, how much compensation reduces the true
flange error.

The whole identified model is used: its table and, when the calibration identified them, its
joint-level errors — transmission error, backlash for the direction the robot comes from (the
rows are executed in order, from home; a program's ``approach1..6`` columns win), compliance
under gravity and the cable's pull at each pose (``--cable-tension 0`` when the encoder is
unhooked while the program runs).
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from twin.cli.arguments import add_robot_flags, integer, number, robot_from_flags, seed
from twin.compensation import (
    InOrder,
    compensate_program,
    compensate_targets,
    identified_arm,
    solve_in_order,
)
from twin.compensation_check import CompensationCheck, check_compensation
from twin.dataset import MAX_POSES, approach_directions
from twin.errors import InputError
from twin.ik import STATUS_OK, STATUS_UNREACHABLE, nominal_ik
from twin.io.atomic import write_atomic
from twin.io.identified import load_result
from twin.io.measurements import approach_columns, joint_columns, load_poses, read_table
from twin.io.paths import InputPath, OutputFile
from twin.metrics import Metrics
from twin.plots import pyplot, save_png
from twin.rig import MAX_TENSION_N
from twin.robot import default_robot
from twin.targets import reachable_targets
from twin.units import FILE_DEG_DECIMALS, MAX_LENGTH_M, m_to_mm, mm_to_m, rad_to_deg, rounded
from twin.unknowns import Stage

TARGET_COLUMNS = ("x", "y", "z")
RESULT_COLUMNS = ("status", "error_mm")
VERIFY_TARGETS = 1000


def add_parser(subparsers: Any) -> None:
    """Register the subcommand."""
    parser = subparsers.add_parser(
        "compensate",
        help="correct joint angles with an identified model, or verify compensation in the twin",
        description="Compute the joint angles to command so that the real (identified) robot "
        "reaches Cartesian flange targets (--targets x,y,z in mm, base frame) or the flange "
        "poses a program written against the nominal model meant (--joints q1..qN in degrees). "
        "Writes q1..qN (deg), a status (ok, unreachable, joint_limit) and the remaining flange "
        "error (mm) per row; nothing is clipped. With --verify SCENARIO.toml: simulate, "
        "calibrate and compare the true flange error with and without compensation.",
    )
    add_robot_flags(parser, "nominal robot model")
    parser.add_argument("--identified", type=InputPath, metavar="RESULT.json",
                        help="calibration result written by `twin calibrate --json`")
    parser.add_argument("--method", help="result to use from a `--method all` result file; "
                        "with --verify, the calibration method (default lm)")
    request = parser.add_mutually_exclusive_group(required=True)
    request.add_argument("--targets", type=InputPath, metavar="TARGETS.csv",
                         help="flange targets, columns x,y,z in mm (- for standard input)")
    request.add_argument("--joints", type=InputPath, metavar="PROGRAM.csv",
                         help="program joint angles, columns q1..qN in degrees (- for "
                         "standard input)")
    request.add_argument("--verify", type=InputPath, metavar="SCENARIO.toml",
                         help="measure compensation in the twin for a scenario")
    parser.add_argument("--out", type=OutputFile, metavar="CORRECTED.csv",
                        help="corrected joint angles (with --targets or --joints)")
    parser.add_argument("--seed", type=seed, help="seed of the random IK starts (default 0) or "
                        "of the simulation (default: the scenario's)")
    parser.add_argument("--count", type=integer(1, MAX_POSES), default=VERIFY_TARGETS,
                        help=f"targets for --verify (default {VERIFY_TARGETS})")
    parser.add_argument("--figure", type=OutputFile, metavar="OUT.png",
                        help="with --verify: histogram of the true flange errors")
    parser.add_argument("--cable-tension", type=number(0.0, MAX_TENSION_N), metavar="N",
                        help="the cable's pull while the robot runs, N, for the compliance "
                        "the result identified (default: the calibration's; 0 when the encoder "
                        "is unhooked)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    if args.verify is not None:
        for flag in ("identified", "out", "robot", "cable_tension"):
            if getattr(args, flag) is not None:
                option = "--" + flag.replace("_", "-")
                raise InputError(f"{option} with --verify",
                                 "--verify SCENARIO.toml alone (the scenario names the robot)",
                                 source=option)
        return _verify(args)
    if args.identified is None or args.out is None:
        missing = "--identified" if args.identified is None else "--out"
        raise InputError(f"no {missing}", "--identified RESULT.json and --out CORRECTED.csv",
                         source=missing)
    robot = robot_from_flags(args) or default_robot()
    model, x, _ = load_result(args.identified, robot, args.method)
    if args.cable_tension is not None:
        model, x = model.with_rig(replace(model.rig, tension_n=args.cable_tension), x)
    if args.joints is not None:
        program = load_poses(args.joints, robot,
                             f"a program CSV (q1..q{robot.n_joints} in degrees)", stdin=True)
        q_nominal = program.q_rad
        if program.approach is not None:
            arm, joints = identified_arm(model, x, program.approach)
            solved = compensate_program(robot, arm, q_nominal, joints)
            approach = program.approach if model.needs_approach else None
            ordered = InOrder(solved, approach, np.zeros(len(q_nominal), dtype=bool))
        else:
            ordered = solve_in_order(model, x, lambda arm, joints: compensate_program(
                robot, arm, q_nominal, joints), q_nominal)
    else:
        xyz_mm, lines = read_table(args.targets, TARGET_COLUMNS, "a target CSV (x,y,z in mm)",
                                   stdin=True)
        far = np.flatnonzero(np.linalg.norm(xyz_mm, axis=1) > m_to_mm(MAX_LENGTH_M))
        if far.size:
            raise InputError(f"a target {np.linalg.norm(xyz_mm[far[0]]):g} mm from the base",
                             f"targets within {float(m_to_mm(MAX_LENGTH_M)):g} mm",
                             source=args.targets, where=f"line {lines[far[0]]}")
        target_m = mm_to_m(xyz_mm)
        nominal = nominal_ik(robot, target_m, np.random.default_rng(args.seed or 0))
        q_nominal = nominal.q_rad
        ordered = solve_in_order(model, x, lambda arm, joints: compensate_targets(
            arm, target_m, q_nominal, joints), q_nominal)
    write_atomic(args.out, format_corrected(ordered))
    print(_summary(ordered, q_nominal))
    print(f"wrote {args.out}")
    return 0


def format_corrected(ordered: InOrder) -> str:
    """CSV text: q1..qN (deg to 1e-6, empty when unreachable), status, remaining flange error
    (mm); with backlash, approach1..N: the side each joint must come from (the corrections hold
    for it)."""
    solved = ordered.solved
    q_deg = rad_to_deg(solved.q_rad)
    error_mm = m_to_mm(solved.position_error_m)
    n = q_deg.shape[1]
    header = [*joint_columns(n), *RESULT_COLUMNS,
              *(approach_columns(n) if ordered.approach is not None else ())]
    lines = [",".join(header)]
    for row, (q, status, error) in enumerate(zip(q_deg, solved.status, error_mm, strict=True)):
        angles = [""] * len(q) if status == STATUS_UNREACHABLE \
            else list(map(repr, rounded(q, FILE_DEG_DECIMALS)))
        sides = [] if ordered.approach is None else [f"{int(s):+d}"
                                                     for s in ordered.approach[row]]
        lines.append(",".join([*angles, str(status), f"{error:.6f}", *sides]))
    return "\n".join(lines) + "\n"


def _summary(ordered: InOrder, q_nominal_rad: NDArray[np.float64]) -> str:
    solved = ordered.solved
    statuses, counts = np.unique(solved.status, return_counts=True)
    text = f"{len(solved.q_rad)} rows: " + ", ".join(
        f"{count} {status}" for status, count in zip(statuses, counts, strict=True))
    ok = solved.status == STATUS_OK
    if np.any(ok):
        change_deg = np.abs(rad_to_deg(solved.q_rad[ok] - q_nominal_rad[ok]))
        text += ("\ncorrection per joint, mean |Δq| [deg]: "
                 + " ".join(f"{v:.4f}" for v in change_deg.mean(axis=0))
                 + f"; largest {change_deg.max():.4f}")
    if np.any(ordered.approach_moves):
        rows = np.flatnonzero(ordered.approach_moves) + 1
        text += (f"\n{rows.size} rows need an approach move (a joint moves less than its "
                 "backlash from the row before: overshoot and come back from the side in "
                 f"approach1..6): rows {', '.join(map(str, rows[:10]))}"
                 + ("…" if rows.size > 10 else ""))
    return text


def _verify(args: argparse.Namespace) -> int:
    """Simulate, calibrate, and compare true flange errors with and without compensation."""
    from twin.calibration import calibrate
    from twin.scenario import load_scenario
    from twin.sim import Twin, simulate

    scenario = load_scenario(args.verify)
    sim = simulate(scenario, seed=args.seed)
    print(f"{scenario.name}: simulated {len(sim.measurements)} poses (seed {sim.seed}); "
          f"calibrating {'+'.join(scenario.errors)}…", flush=True)
    rig = replace(sim.rig_told, tension_n=scenario.physics.tension_n)
    result = calibrate(sim.robot, sim.measurements, rig=rig, errors=scenario.errors,
                       method=args.method or "lm", seed=sim.seed, budget=scenario.budget,
                       estimate_port=scenario.estimate_port,
                       estimate_offset=scenario.estimate_offset,
                       estimate_attachment=scenario.estimate_attachment,
                       estimate_base=scenario.estimate_base, loss=scenario.calibration_loss)
    validation = result.metrics["validation"]
    print(f"  {result.method}: validation RMSE {m_to_mm(validation.rmse):.4f} mm "
          f"(before {m_to_mm(result.metrics['before'].rmse):.4f} mm)")
    twin = Twin.build(sim.true_robot, sim.port_m, scenario.physics, sim.joint_errors,
                      sim.rig.attachment_m)
    rng = np.random.default_rng(sim.seed)
    q_nominal, target_m = reachable_targets(sim.robot, args.count, rng)
    print(f"{args.count} random reachable targets: solving and moving the true robot…",
          flush=True)
    # The robot visits the targets in order from home; the twin's joints then come from the
    # directions of the commands actually sent.
    at_nominal = twin.flange_positions(q_nominal, approach_directions(q_nominal))
    extended = any(group.stage == Stage.JOINTS for group in result.model.groups)
    ordered = solve_in_order(result.model, result.x, lambda arm, joints: compensate_targets(
        arm, target_m, q_nominal, joints), q_nominal)
    solutions = {
        "identified model" if extended else "identified table": ordered.solved,
        "true D-H table": compensate_targets(sim.true_robot, target_m, q_nominal),
    }
    checks = {}
    for label, solved in solutions.items():
        # Approach moves where the compensation asks for them, else straight from the row
        # before.
        approach = approach_directions(solved.q_rad) if ordered.approach is None \
            or solved is not ordered.solved else ordered.approach
        reached = twin.flange_positions(solved.q_rad, approach)
        checks[label] = check_compensation(target_m, at_nominal, reached, solved)
    print(format_checks(checks))
    if np.any(ordered.approach_moves):
        print(f"  ({int(np.sum(ordered.approach_moves))} targets reached with an approach move: "
              "a joint moves less than its backlash from the target before)")
    if args.figure is not None:
        _write_histogram(args.figure, checks, f"{scenario.name}, seed {sim.seed}")
        print(f"wrote {args.figure}")
    return 0


def _row(label: str, m: Metrics) -> str:
    return (f"  {label:<34}{m_to_mm(m.mae):>10.4f}{m_to_mm(m.rmse):>10.4f}"
            f"{m_to_mm(m.max):>10.4f}")


def format_checks(checks: dict[str, CompensationCheck]) -> str:
    """Table of true flange errors (mm): nominal, then each compensation."""
    first = next(iter(checks.values()))
    lines = ["true flange error [mm]                  mean       RMS       max",
             _row("nominal joints", first.nominal)]
    for label, check in checks.items():
        note = f"  ({check.n_failed} of {check.n_targets} not solved)" if check.n_failed else ""
        lines.append(_row(f"compensated, {label}", check.compensated) + note)
    return "\n".join(lines)


def _write_histogram(path: Path, checks: dict[str, CompensationCheck], title: str) -> None:
    """PNG: histograms of the true flange error without and with compensation (log x)."""
    plt = pyplot()
    first = next(iter(checks.values()))
    series = [("nominal joints", first.nominal_error_m)] + [
        (f"compensated, {label}", check.compensated_error_m) for label, check in checks.items()
    ]
    errors_mm = np.concatenate([m_to_mm(values) for _, values in series])
    low = max(float(errors_mm.min()), 1e-6)
    bins = np.geomspace(low, float(errors_mm.max()), 60).tolist()
    figure, axes = plt.subplots(figsize=(6.4, 4.0), layout="constrained")
    for label, values in series:
        rms = float(m_to_mm(np.sqrt(np.mean(values**2))))
        axes.hist(np.maximum(m_to_mm(values), low), bins=bins, alpha=0.6,
                  label=f"{label} (RMS {rms:.4f} mm)")
    axes.set_xscale("log")
    axes.set_xlabel("true flange position error [mm]")
    axes.set_ylabel("targets")
    axes.legend(fontsize=8)
    axes.set_title(title, fontsize=9)
    save_png(figure, path)
