"""`twin compensate`: joint angles that make the identified robot go where it should.

With ``--targets`` (positions x,y,z in mm, with an orientation and a configuration if given) or
``--joints`` (a program q1..q6 in degrees, written against the nominal model) it writes corrected
joint angles with a per-row status; with ``--rapid IN.mod`` it rewrites a RAPID module's targets
(program filtering, :mod:`twin.io.rapid_filter`); with ``--verify SCENARIO.toml`` it measures, in
the MuJoCo twin, how much compensation reduces the true flange error.

The whole identified model is used: its table and, when the calibration identified them, its
joint-level errors — transmission error, backlash for the direction the robot comes from (the
rows are executed in order, from home; a program's ``approach1..6`` columns win), compliance
under gravity and the cable's pull at each pose (``--cable-tension 0`` when the encoder is
unhooked while the program runs).
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from typing import TYPE_CHECKING

from twin.choices import MAX_POSES
from twin.cli.arguments import (
    RESULT_ROBOT,
    add_cable_tension,
    add_output,
    add_result,
    add_robot_flags,
    add_seed,
    add_temperature,
    given_robot,
    integer,
)
from twin.errors import InputError
from twin.io.paths import InputPath

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from twin.analysis.metrics import Metrics
    from twin.compensation.check import CompensationCheck
    from twin.compensation.joints import InOrder
    from twin.model import Model
    from twin.robot import RobotModel


VERIFY_TARGETS = 1000


NAME = "compensate"
HELP = "correct joint angles with an identified model, or verify compensation in the twin"
DESCRIPTION = (
    "Compute the joint angles to command so that the real (identified) robot "
    "reaches Cartesian flange targets (--targets x,y,z in mm, base frame) or the flange "
    "poses a program written against the nominal model meant (--joints q1..qN in degrees). "
    "Writes q1..qN (deg), a status (ok, unreachable, joint_limit, singular) and the "
    "remaining flange "
    "error (mm) per row; nothing is clipped. With --verify SCENARIO.toml: simulate, "
    "calibrate and compare the true flange error with and without compensation."
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The subcommand's arguments."""
    add_robot_flags(parser, RESULT_ROBOT)
    add_result(parser, required=False)
    parser.add_argument("--method", help="result to use from a `--method all` result file; "
                        "with --verify, the calibration method (default lm)")
    request = parser.add_mutually_exclusive_group(required=True)
    request.add_argument("--targets", type=InputPath, metavar="TARGETS.csv",
                         help="flange targets, columns x,y,z in mm (- for standard input)")
    request.add_argument("--joints", type=InputPath, metavar="PROGRAM.csv",
                         help="program joint angles, columns q1..qN in degrees (- for "
                         "standard input)")
    request.add_argument("--rapid", type=InputPath, metavar="IN.mod",
                         help="a RAPID module: every jointtarget and robtarget rewritten for the "
                         "identified robot, every other byte kept (--out OUT.mod)")
    request.add_argument("--verify", type=InputPath, metavar="SCENARIO.toml",
                         help="measure compensation in the twin for a scenario")
    add_output(parser, "CORRECTED.csv", "corrected joint angles (with --targets or --joints), "
               "or the filtered module (with --rapid)", required=False)
    parser.add_argument("--tool", action="append", metavar="[NAME=]X,Y,Z[,QW,QX,QY,QZ]",
                        help="a tool: its TCP in the controller's flange frame tool0, mm and a "
                        "unit quaternion (ABB's tooldata.tframe). With --targets one, unnamed; "
                        "with --rapid NAME= a tool the module uses but does not declare (wins "
                        "over its declaration), unnamed for targets no instruction moves to")
    parser.add_argument("--wobj", action="append", metavar="[NAME=]X,Y,Z[,QW,QX,QY,QZ]",
                        help="a work object: its frame in the robot's base frame, mm and a unit "
                        "quaternion (ABB's uframe·oframe); named as --tool")
    parser.add_argument("--tool0-in-flange", metavar="X,Y,Z,QW,QX,QY,QZ",
                        help="the controller's flange frame tool0 in twin's flange frame (mm, "
                        "quaternion); needed with orientations unless the robot is a URDF chain "
                        "ending at tool0 or a shipped model (the IRB 120: a half turn about z)")
    add_seed(parser, "seed of the random IK starts (default 0) or of the simulation (default: "
             "the scenario's)")
    parser.add_argument("--count", type=integer(1, MAX_POSES), default=VERIFY_TARGETS,
                        help=f"targets for --verify (default {VERIFY_TARGETS})")
    add_output(parser, "OUT.png", "with --verify: histogram of the true flange errors",
               flag="--figure", required=False)
    add_cable_tension(parser, "the cable's pull while the robot runs, N, for the compliance the "
                      "result identified (default: the calibration's; 0 when the encoder is "
                      "unhooked)")
    add_temperature(parser, "the compensation")


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    import numpy as np

    from twin.compensation.joints import compensate_program_rows
    from twin.io.identified import (
        at_temperature,
        load_result,
        warn_result_cautions,
        warn_temperature,
    )
    from twin.io.measurements import joint_units_said, load_poses
    from twin.io.pose_tables import write_corrected

    if args.verify is not None:
        for flag in ("identified", "out", "robot", "xacro_arg", "cable_tension", "tool", "wobj",
                     "tool0_in_flange", "temperature_c"):
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
    result = load_result(args.identified, given_robot(args), args.method)
    robot = result.model.robot  # the program's: the nominal at its own lengths
    model, x, _ = at_temperature(result, args.temperature_c, args.identified)
    if args.cable_tension is not None:
        model, x = model.with_rig(replace(model.rig, tension_n=args.cable_tension), x)
    rng = np.random.default_rng(args.seed or 0)
    if args.rapid is not None:
        return _rapid(args, robot, model, x, rng)
    if args.joints is not None:
        if args.tool or args.wobj:
            raise InputError("--tool or --wobj with --joints", "them with --targets or --rapid",
                             source="--tool" if args.tool else "--wobj")
        program = load_poses(args.joints, robot,
                             f"a program CSV ({joint_units_said(robot.n_joints, robot)})",
                             stdin=True)
        q_nominal = program.q_rad
        ordered = compensate_program_rows(model, x, robot, q_nominal, program.approach)
    else:
        ordered, q_nominal = _targets(args, robot, model, x, rng)
    # After every input is checked: a refusal stays one line.
    warn_result_cautions(args.identified, args.method, "the compensated program")
    warn_temperature(result, args.temperature_c, args.identified, "the compensated program")
    write_corrected(args.out, ordered, robot)
    print(_summary(ordered, q_nominal, robot))
    print(f"wrote {args.out}")
    return 0


def _targets(args: argparse.Namespace, robot: RobotModel, model: Model, x: NDArray[np.float64],
             rng: np.random.Generator) -> tuple[InOrder, NDArray[np.float64]]:
    """Targets of a CSV: flange positions, or full TCP poses in a work object with a tool."""
    import numpy as np

    from twin.cli.frames import parse_frames
    from twin.compensation.joints import compensate_pose_rows, compensate_target_rows
    from twin.compensation.poses import flange_targets
    from twin.io.pose_tables import load_pose_targets

    targets = load_pose_targets(args.targets, stdin=True)
    frames = parse_frames(args)
    if any(name is not None for name in (*frames.tools, *frames.wobjs)):
        raise InputError("a named --tool or --wobj with --targets", "X,Y,Z[,QW,QX,QY,QZ] "
                         "without a name (one tool and one work object for every row)",
                         source="--tool")
    if targets.rotation is None:
        if frames.tools or frames.wobjs or targets.configuration is not None:
            raise InputError(f"{args.targets} without an orientation", "qw,qx,qy,qz or rx,ry,rz "
                             "columns with --tool, --wobj or cf1..cfx (a TCP position alone "
                             "leaves the flange anywhere on a sphere)", source=args.targets)
        return compensate_target_rows(model, x, robot, targets.position_m, rng)
    poses = np.tile(np.eye(4), (len(targets.position_m), 1, 1))
    poses[:, :3, :3], poses[:, :3, 3] = targets.rotation, targets.position_m
    base_T_flange = flange_targets(poses, frames.wobjs.get(None, np.eye(4)),
                                   frames.tools.get(None, np.eye(4)), _tool0(args, robot))
    solved = compensate_pose_rows(model, x, robot, base_T_flange, rng, targets.configuration)
    return solved.ordered, solved.nominal.q_rad


def _tool0(args: argparse.Namespace, robot: RobotModel) -> NDArray[np.float64]:
    """The controller's tool0 in twin's flange frame: the flag's, or what twin knows."""
    from twin.cli.frames import parse_pose_mm
    from twin.compensation.poses import controller_tool0

    if args.tool0_in_flange is not None:
        return parse_pose_mm(args.tool0_in_flange, "--tool0-in-flange", full=True)
    known = controller_tool0(robot)
    if known is None:
        raise InputError(f"orientations for {robot.name}, whose controller flange frame (tool0) "
                         "twin does not know", "--tool0-in-flange X,Y,Z,QW,QX,QY,QZ: the "
                         "controller's tool0 in twin's flange frame (mm, quaternion)",
                         source="--tool0-in-flange")
    return known


def _rapid(args: argparse.Namespace, robot: RobotModel, model: Model, x: NDArray[np.float64],
           rng: np.random.Generator) -> int:
    """Filter a RAPID module: every target rewritten, the rest of it byte for byte."""
    from twin.cli.frames import RAPID_SUFFIXES, parse_frames
    from twin.compensation.poses import controller_tool0
    from twin.io.atomic import write_atomic
    from twin.io.identified import warn_result_cautions
    from twin.io.rapid import ENCODING, read_module
    from twin.io.rapid_filter import filter_module, format_filter_rows

    if args.out.suffix.lower() not in RAPID_SUFFIXES:
        raise InputError(f"{args.out}", "an output RAPID module (.mod, .modx, .sys)",
                         source="--out")
    module = read_module(args.rapid)
    tool0 = _tool0(args, robot) if args.tool0_in_flange is not None \
        or controller_tool0(robot) is not None else None
    filtered = filter_module(module, model, x, robot, tool0, parse_frames(args), rng)
    warn_result_cautions(args.identified, args.method, "the compensated module")
    write_atomic(args.out, filtered.text.encode(ENCODING))
    print(format_filter_rows(filtered.rows))
    print(f"wrote {args.out}")
    return 0


def _summary(ordered: InOrder, q_nominal_rad: NDArray[np.float64], robot: RobotModel) -> str:
    import numpy as np

    from twin.compensation.ik import STATUS_OK
    from twin.report.display import deg, joint_values, mm

    solved = ordered.solved
    statuses, counts = np.unique(solved.status, return_counts=True)
    text = f"{len(solved.q_rad)} rows: " + ", ".join(
        f"{count} {status}" for status, count in zip(statuses, counts, strict=True))
    ok = solved.status == STATUS_OK
    if np.any(ok):
        change = np.abs(solved.q_rad[ok] - q_nominal_rad[ok])
        mean, units = joint_values(change.mean(axis=0), robot.prismatic, separator=" ")
        sliding = robot.prismatic
        largest = ([deg(change[:, ~sliding].max(), unit=bool(sliding.any()))]
                   if not sliding.all() else []) \
            + ([mm(change[:, sliding].max())] if sliding.any() else [])
        text += (f"\ncorrection per joint, mean |Δq| [{units}]: {mean}; largest "
                 + ", ".join(largest))
    if np.any(ordered.approach_moves):
        rows = np.flatnonzero(ordered.approach_moves) + 1
        text += (f"\n{rows.size} rows need an approach move (a joint moves less than its "
                 "backlash from the row before: overshoot and come back from the side in "
                 f"approach1..{robot.n_joints}): rows {', '.join(map(str, rows[:10]))}"
                 + ("…" if rows.size > 10 else ""))
    return text


def _verify(args: argparse.Namespace) -> int:
    """Simulate, calibrate, and compare true flange errors with and without compensation."""
    from twin.io.png import save_png
    from twin.report.plots import compensation_histogram
    from twin.scenario import load_scenario
    from twin.sim.verification import verify_compensation

    scenario = load_scenario(args.verify)
    verification = verify_compensation(scenario, seed=args.seed, method=args.method or "lm",
                                       count=args.count,
                                       progress=lambda line: print(line, flush=True))
    print(format_checks(verification.checks))
    if verification.approach_moves:
        print(f"  ({verification.approach_moves} targets reached with an approach move: "
              "a joint moves less than its backlash from the target before)")
    if args.figure is not None:
        save_png(compensation_histogram(
            verification.checks, f"{scenario.name}, seed {verification.simulation.seed}"),
            args.figure)
        print(f"wrote {args.figure}")
    return 0


def _row(label: str, m: Metrics) -> str:
    from twin.report.display import mm

    return f"  {label:<34}" + "".join(mm(v, width=10, unit=False) for v in (m.mae, m.rmse, m.max))


def format_checks(checks: dict[str, CompensationCheck]) -> str:
    """Table of true flange errors (mm): nominal, then each compensation."""
    first = next(iter(checks.values()))
    lines = ["true flange error [mm]                  mean       RMS       max",
             _row("nominal joints", first.nominal)]
    for label, check in checks.items():
        note = f"  ({check.n_failed} of {check.n_targets} not solved)" if check.n_failed else ""
        lines.append(_row(f"compensated, {label}", check.compensated) + note)
    return "\n".join(lines)
