"""`twin plan`: a D-optimal pose plan for a cable calibration, and where to put the port.

Candidates come from the MuJoCo twin's feasibility sampler (imported lazily in `run`), unless
``--joint-limits-only``: the design itself (:mod:`twin.design`) is pure numpy. ``--errors``
plans for the error groups the calibration will fit; with backlash, each candidate is taken as
approached from the one before it (random candidates: random sides) and the plan is scored for
the sides of visiting it in order, as `twin capture` does.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from twin.calibration import WORKSPACE_POSES, make_model
from twin.cli.arguments import (
    add_robot_flags,
    error_groups,
    integer,
    number,
    robot_from_flags,
    seed,
    sigma_mm,
)
from twin.dataset import MAX_POSES
from twin.design import DesignScore, choose_port, plan_stations, score_poses
from twin.errors import InputError
from twin.io.atomic import write_atomic
from twin.io.capture_file import parse_named_port
from twin.io.measurements import PORT_COLUMN, joint_columns
from twin.io.paths import OutputFile
from twin.model import Model
from twin.rig import MAX_TENSION_N, Rig
from twin.robot import RobotModel, default_robot
from twin.synthetic import random_poses
from twin.units import FILE_DEG_DECIMALS, m_to_mm, mm_to_m, rad_to_deg, rounded
from twin.unknowns import ERRORS

DEFAULT_CANDIDATES = 2000
"""Candidate poses drawn within the joint limits."""


def add_parser(subparsers: Any) -> None:
    """Register the subcommand."""
    parser = subparsers.add_parser(
        "plan",
        help="choose the poses (and the port) that measure the D-H errors best",
        description="Pick N poses among random candidates the rig can measure that "
        "maximise det(JᵀJ) of the base parameters at the nominal geometry (D-optimal: greedy, "
        "then exchanges), write them as a plan CSV (q1..qN in degrees) and compare the plan "
        "with N random poses. Given several --port, plan for each and keep the port whose "
        "plan predicts the smallest flange error over the workspace.",
    )
    add_robot_flags(parser)
    parser.add_argument("--port", action="append", required=True, metavar="[NAME=]X,Y,Z",
                        help="encoder port in mm, robot base frame; repeat X,Y,Z to choose "
                        "among several, or give NAME=X,Y,Z for each station of an encoder "
                        "moved between them: poses and stations are then planned together "
                        "(the plan gets a port column)")
    parser.add_argument("--poses", type=integer(1, MAX_POSES), required=True, metavar="N",
                        help="poses to plan")
    parser.add_argument("--candidates", type=integer(1, MAX_POSES), default=DEFAULT_CANDIDATES,
                        metavar="M", help=f"random candidate poses (default {DEFAULT_CANDIDATES})")
    parser.add_argument("--seed", type=seed, default=0, help="seed of every random draw")
    parser.add_argument("--sigma", type=sigma_mm, default=0.01, metavar="MM",
                        help="length noise 1σ in mm for the predicted accuracy (default 0.01)")
    parser.add_argument("--estimate-port", action="store_true",
                        help="plan for a calibration that also identifies the port")
    parser.add_argument("--estimate-offset", action="store_true",
                        help="plan for a calibration that also identifies a length offset")
    parser.add_argument("--errors", type=error_groups(auto=False), default=("dh",),
                        metavar="GROUPS", help="the robot's error groups the calibration will "
                        "fit, comma-separated: " + ", ".join(ERRORS) + " (default: dh)")
    parser.add_argument("--cable-tension", type=number(0.0, MAX_TENSION_N), default=0.0,
                        metavar="N", help="the cable's pull, N, which loads the joints for the "
                        "compliance group (default 0: gravity alone)")
    parser.add_argument("--joint-limits-only", dest="feasible", action="store_false",
                        help="draw candidate (and random) poses within the joint limits only; "
                        "by default they are poses the rig can measure: flange above the "
                        "floor, no collision, cable in range and clear of the links (the MuJoCo "
                        "twin's default constraints, per port)")
    parser.add_argument("--out", type=OutputFile, required=True, metavar="plan.csv",
                        help="where to write the plan")
    parser.set_defaults(func=run)


def _score_row(label: str, score: DesignScore) -> str:
    o = score.observability
    return (f"  {label:<8}{o.o1:>11.4g}{o.o3:>11.4g}{o.o4:>11.4g}{o.condition:>11.4g}"
            f"{float(m_to_mm(score.flange_rms_m)):>14.4f}")


def _feasible_sampler(
    robot: RobotModel, rng: np.random.Generator
) -> Callable[[NDArray[np.float64], int], NDArray[np.float64]]:
    """``draw(port_m, count)``: poses the MuJoCo twin with that port can measure."""
    from twin.scenario import PoseConstraints
    from twin.sim.mujoco_twin import Twin
    from twin.sim.poses import sample_poses

    constraints = PoseConstraints()

    def draw(port_m: NDArray[np.float64], count: int) -> NDArray[np.float64]:
        try:
            return sample_poses(Twin.build(robot, port_m), count, constraints, rng)
        except InputError as exc:
            port = ",".join(f"{v:g}" for v in m_to_mm(port_m))
            raise InputError(exc.found, exc.expected + " (or --joint-limits-only)",
                             source=f"--port {port}") from None

    return draw


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    robot = robot_from_flags(args) or default_robot()
    parsed = [parse_named_port(value, "--port", "") for value in args.port]
    names = [name for name, _ in parsed if name is not None]
    if names:
        if len(names) != len(parsed) or len(set(names)) != len(names):
            raise InputError("named and unnamed ports, or a name twice", "NAME=X,Y,Z for every "
                             "station (planned together), or X,Y,Z candidates (one is chosen)",
                             source="--port")
        return _run_stations(args, robot, Rig(np.stack([port for _, port in parsed]),
                                              tuple(names), tension_n=args.cable_tension))
    ports_m = np.stack([port for _, port in parsed])

    def model_at(port_m: NDArray[np.float64]) -> Model:
        return make_model(robot, Rig.cable(port_m, tension_n=args.cable_tension),
                          errors=args.errors, estimate_port=args.estimate_port,
                          estimate_offset=args.estimate_offset)

    model = model_at(ports_m[0])
    if not model.n_params <= args.poses <= args.candidates:
        raise InputError(f"{args.poses} poses from {args.candidates} candidates",
                         f"at least {model.n_params} poses (the unknowns) and no more than "
                         "the candidates", source="--poses")
    rng = np.random.default_rng(args.seed)
    draw = _feasible_sampler(robot, rng) if args.feasible else (
        lambda port_m, count: random_poses(robot, count, rng))
    q_workspace = random_poses(robot, WORKSPACE_POSES, rng)
    candidates = np.stack([draw(port, args.candidates) for port in ports_m])
    sigma_m = float(mm_to_m(args.sigma))
    choice = choose_port(model, ports_m, candidates, args.poses, sigma_m, q_workspace)
    port_m = ports_m[choice.best]
    plan = choice.plans[choice.best]
    q_random = draw(port_m, args.poses)
    at_port = model_at(port_m)
    x0 = np.zeros(model.n_params)
    planned = score_poses(at_port, x0, plan.q_rad, plan.base_mask, sigma_m, q_workspace)
    drawn = score_poses(at_port, x0, q_random, plan.base_mask, sigma_m, q_workspace)
    rows = [",".join(joint_columns(robot.n_joints))]
    rows += [",".join(map(repr, rounded(q, FILE_DEG_DECIMALS))) for q in rad_to_deg(plan.q_rad)]
    write_atomic(args.out, "\n".join(rows) + "\n")
    lines = []
    if len(ports_m) > 1:
        lines.append("port candidates [mm]        predicted flange RMS [mm]")
        for k, (port, rms) in enumerate(zip(ports_m, choice.flange_rms_m, strict=True)):
            text = ", ".join(f"{v:g}" for v in m_to_mm(port))
            lines.append(f"  ({text}){'':<{max(1, 24 - len(text))}}{float(m_to_mm(rms)):.4f}"
                         + ("   <- chosen" if k == choice.best else ""))
    port_text = ", ".join(f"{v:g}" for v in m_to_mm(port_m))
    lines += [
        f"{robot.name}: {args.poses} D-optimal poses of {args.candidates} "
        f"{'feasible ' if args.feasible else ''}candidates "
        f"({plan.selection.exchanges} exchanges), port ({port_text}) mm, "
        f"{plan.base_mask.sum()} base parameters of {model.n_params} unknowns",
        "  poses           O1         O3         O4  condition  flange RMS [mm]",
        _score_row("planned", planned),
        _score_row("random", drawn),
        f"  (base-parameter columns in SI; flange RMS: Cramér–Rao at σ = {args.sigma:g} mm "
        f"over {WORKSPACE_POSES} workspace poses; random: {args.poses} poses drawn with the "
        "same seed and constraints)",
        f"plan: {args.out}",
    ]
    print("\n".join(lines))
    return 0


def _run_stations(args: argparse.Namespace, robot: RobotModel, rig: Rig) -> int:
    """Plan poses and stations together for an encoder moved between named ports."""
    model = make_model(robot, rig, errors=args.errors, estimate_port=args.estimate_port,
                       estimate_offset=args.estimate_offset)
    if not model.n_params <= args.poses <= args.candidates * len(rig.ports_m):
        raise InputError(f"{args.poses} poses from {args.candidates} candidates per station",
                         f"at least {model.n_params} poses (the unknowns) and no more than "
                         "the candidates", source="--poses")
    rng = np.random.default_rng(args.seed)
    draw = _feasible_sampler(robot, rng) if args.feasible else (
        lambda port_m, count: random_poses(robot, count, rng))
    q_workspace = random_poses(robot, WORKSPACE_POSES, rng)
    candidates = np.stack([draw(port, args.candidates) for port in rig.ports_m])
    sigma_m = float(mm_to_m(args.sigma))
    x0 = np.zeros(model.n_params)
    plan = plan_stations(model, x0, candidates, args.poses)
    share, extra = divmod(args.poses, len(rig.ports_m))
    counts = [share + (k < extra) for k in range(len(rig.ports_m))]
    q_random = np.concatenate([draw(port, count) for port, count
                               in zip(rig.ports_m, counts, strict=True)])
    port_random = np.repeat(np.arange(len(rig.ports_m)), counts)
    planned = score_poses(model, x0, plan.q_rad, plan.base_mask, sigma_m, q_workspace,
                          plan.port)
    drawn = score_poses(model, x0, q_random, plan.base_mask, sigma_m, q_workspace,
                        port_random)
    rows = [",".join((*joint_columns(robot.n_joints), PORT_COLUMN))]
    rows += [",".join([*map(repr, rounded(q, FILE_DEG_DECIMALS)), rig.port_names[j]])
             for q, j in zip(rad_to_deg(plan.q_rad), plan.port, strict=True)]
    write_atomic(args.out, "\n".join(rows) + "\n")
    used = np.bincount(plan.port, minlength=len(rig.ports_m))
    lines = [
        f"{robot.name}: {args.poses} D-optimal (pose, station) pairs of "
        f"{args.candidates} {'feasible ' if args.feasible else ''}candidates per station "
        f"({plan.selection.exchanges} exchanges), {plan.base_mask.sum()} base parameters of "
        f"{model.n_params} unknowns",
        "  stations: " + ", ".join(f"{name} {int(count)} poses" for name, count
                                   in zip(rig.port_names, used, strict=True)),
        "  poses           O1         O3         O4  condition  flange RMS [mm]",
        _score_row("planned", planned),
        _score_row("random", drawn),
        f"  (base-parameter columns in SI; flange RMS: Cramér–Rao at σ = {args.sigma:g} mm "
        f"over {WORKSPACE_POSES} workspace poses, modulo what the data cannot see; random: "
        f"{args.poses} poses shared evenly between the stations, drawn with the same seed and "
        "constraints)",
        f"plan: {args.out} (column port: the station of each pose)",
    ]
    print("\n".join(lines))
    return 0
