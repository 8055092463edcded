"""`twin plan`: a D-optimal pose plan for a cable calibration, and where to put the port.

Candidates come from the MuJoCo twin's feasibility sampler, unless ``--joint-limits-only``
(:mod:`twin.design.planning`); the design itself (:mod:`twin.design.optimal`) is pure numpy.
``--errors`` plans for the error groups the calibration will fit; with backlash, each candidate is
taken as approached from the one before it (random candidates: random sides) and the plan is scored
for the sides of visiting it in order, as `twin capture` does.
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from twin.choices import DEFAULT_SETTLE_S, DEFAULT_SPEED, MAX_POSES
from twin.cli.arguments import (
    add_cable_tension,
    add_error_groups,
    add_output,
    add_robot_flags,
    add_seed,
    integer,
    number,
    robot_from_flags,
    sigma_mm,
)
from twin.errors import InputError
from twin.unknowns import ERRORS

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from twin.design.optimal import DesignScore
    from twin.design.planning import PortPlan, SamplerFactory, StationsPlan
    from twin.io.rapid_plan import PlanOptions
    from twin.model import Model
    from twin.rig import Rig
    from twin.robot import RobotModel


DEFAULT_CANDIDATES = 2000
"""Candidate poses drawn within the joint limits."""


NAME = "plan"
HELP = "choose the poses (and the port) that measure the D-H errors best"
DESCRIPTION = (
    "Pick N poses among random candidates the rig can measure that "
    "maximise det(JᵀJ) of the base parameters at the nominal geometry (D-optimal: greedy, "
    "then exchanges), write them as a plan CSV (q1..qN in degrees) and compare the plan "
    "with N random poses. Given several --port, plan for each and keep the port whose "
    "plan predicts the smallest flange error over the workspace."
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The subcommand's arguments."""
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
    add_seed(parser, "seed of every random draw", default=0)
    parser.add_argument("--sigma", type=sigma_mm, default=0.01, metavar="MM",
                        help="length noise 1σ in mm for the predicted accuracy (default 0.01)")
    parser.add_argument("--estimate-port", action="store_true",
                        help="plan for a calibration that also identifies the port")
    parser.add_argument("--estimate-offset", action="store_true",
                        help="plan for a calibration that also identifies a length offset")
    parser.add_argument("--estimate-scale", action="store_true",
                        help="plan for a calibration that also identifies the encoder's scale")
    add_error_groups(parser, "the robot's error groups the calibration will fit, "
                     "comma-separated: " + ", ".join(ERRORS) + " (default: dh)", default=("dh",))
    add_cable_tension(parser, "the cable's pull, N, which loads the joints for the compliance "
                      "group (default 0: gravity alone)", default=0.0)
    parser.add_argument("--joint-limits-only", dest="feasible", action="store_false",
                        help="draw candidate (and random) poses within the joint limits only; "
                        "by default they are poses the rig can measure: flange above the "
                        "floor, no collision, cable in range and clear of the links (the MuJoCo "
                        "twin's default constraints, per port)")
    parser.add_argument("--reference-every", type=integer(1, MAX_POSES), default=None,
                        metavar="N", help="after every N poses (and at the end) revisit the "
                        "first, flagged in the plan's reference column, so that `twin "
                        "calibrate` can test the capture for drift (default: no revisits)")
    add_output(parser, "plan.csv", "where to write the plan: a CSV, or with .mod a RAPID "
               "module that drives an ABB robot through it with a capture handshake "
               "(docs/compensation.md)")
    parser.add_argument("--speed", default=None, metavar="SPEEDDATA",
                        help=f"with .mod: the moves' speed, one of ABB's speeddata "
                        f"(default {DEFAULT_SPEED})")
    parser.add_argument("--tool", default=None, metavar="NAME",
                        help="with .mod: the tooldata the moves name (default tool0)")
    parser.add_argument("--wobj", default=None, metavar="NAME",
                        help="with .mod: the wobjdata the moves name (default wobj0)")
    parser.add_argument("--settle", type=number(0.0, 60.0), default=None, metavar="S",
                        help=f"with .mod: the wait at each pose before it is read, s (default "
                        f"{DEFAULT_SETTLE_S:g})")
    parser.add_argument("--home", default=None, metavar="Q1,…,Q6",
                        help="with .mod: the joints (deg) the robot starts and ends at (default "
                        "every joint at 0 but joint 5 at 30)")


def _score_row(label: str, score: DesignScore) -> str:
    from twin.report.display import mm

    o = score.observability
    return (f"  {label:<8}{o.o1:>11.4g}{o.o3:>11.4g}{o.o4:>11.4g}{o.condition:>11.4g}"
            f"{mm(score.flange_rms_m, width=14, unit=False)}")


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    import numpy as np

    from twin.design.planning import plan_for_ports, plan_for_stations
    from twin.io.capture_file import UNKNOWN_PORT, parse_named_port
    from twin.rig import Rig
    from twin.units import mm_to_m

    robot = robot_from_flags(args)
    _check_module_flags(args, robot)
    for value in args.port:
        if value.partition("=")[2 if "=" in value else 0].strip() == UNKNOWN_PORT:
            raise InputError(f"--port {value}", "the port's position X,Y,Z in mm: a plan "
                             "chooses poses for where the cable runs, so it needs a guess "
                             "(a tape measure's is enough; calibrate then takes --port unknown)",
                             source="--port")
    parsed = [parse_named_port(value, "--port", "") for value in args.port]
    names = [name for name, _ in parsed if name is not None]
    sigma_m = float(mm_to_m(args.sigma))
    if names:
        if len(names) != len(parsed) or len(set(names)) != len(names):
            raise InputError("named and unnamed ports, or a name twice", "NAME=X,Y,Z for every "
                             "station (planned together), or X,Y,Z candidates (one is chosen)",
                             source="--port")
        rig = Rig(np.stack([port for _, port in parsed]), tuple(names),
                  tension_n=args.cable_tension)
        model = _model(args, robot, rig)
        _check_poses(args, model, len(rig.ports_m), " per station")
        stations = plan_for_stations(model, rig, args.poses, args.candidates, sigma_m,
                                     seed=args.seed, sampler=_sampler(args))
        order = _write(args, robot, stations.q_rad, rig.port_names, stations.port)
        print(_stations_report(args, robot, model, rig, stations))
        print(order)
        return 0
    ports_m = np.stack([port for _, port in parsed])

    def model_at(port_m: NDArray[np.float64]) -> Model:
        return _model(args, robot, Rig.cable(port_m, tension_n=args.cable_tension))

    model = model_at(ports_m[0])
    _check_poses(args, model, 1, "")
    plan = plan_for_ports(model_at, ports_m, args.poses, args.candidates, sigma_m,
                          seed=args.seed, sampler=_sampler(args))
    order = _write(args, robot, plan.q_rad)
    print(_ports_report(args, robot, model, ports_m, plan))
    print(order)
    return 0


def _check_module_flags(args: argparse.Namespace, robot: RobotModel) -> PlanOptions | None:
    """The RAPID options when --out names a module (checked before any work), else None."""
    import numpy as np

    from twin.io.rapid_plan import PlanOptions, check_identifier, plan_module
    from twin.units import deg_to_rad

    flags = {"--speed": args.speed, "--tool": args.tool, "--wobj": args.wobj,
             "--settle": args.settle, "--home": args.home}
    if args.out.suffix.lower() != ".mod":
        given = [flag for flag, value in flags.items() if value is not None]
        if given:
            raise InputError(f"{given[0]} with a CSV plan", "it with --out PLAN.mod (a RAPID "
                             "module)", source=given[0])
        return None
    home = None
    if args.home is not None:
        try:
            home_deg = [float(v) for v in args.home.split(",")]
        except ValueError:
            home_deg = []
        if len(home_deg) != robot.n_joints or not np.all(np.isfinite(home_deg)):
            raise InputError(f"{args.home!r}", f"{robot.n_joints} angles in degrees",
                             source="--home")
        home = deg_to_rad(home_deg)
    options = PlanOptions(speed=args.speed or DEFAULT_SPEED,
                          tool=check_identifier(args.tool or "tool0", "--tool"),
                          wobj=check_identifier(args.wobj or "wobj0", "--wobj"),
                          settle_s=DEFAULT_SETTLE_S if args.settle is None else args.settle,
                          home_rad=home)
    plan_module(robot, np.zeros((0, robot.n_joints)), options)  # checks speed, joints, home
    return options


def _write(args: argparse.Namespace, robot: RobotModel, q_rad: NDArray[np.float64],
           port_names: tuple[str, ...] = (), port: NDArray[np.intp] | None = None) -> str:
    """The plan, in a short visiting order from home, as a CSV or (.mod) as a RAPID module;
    the line that says the order's travel."""
    from twin.compensation.ik import home_pose
    from twin.dataset import reference_visits
    from twin.design.order import visiting_order
    from twin.io.atomic import write_atomic
    from twin.io.pose_tables import write_plan
    from twin.io.rapid_plan import plan_module

    options = _check_module_flags(args, robot)
    home = home_pose(robot) if options is None or options.home_rad is None \
        else options.home_rad
    visit = visiting_order(robot, q_rad, home, port)
    # The revisits go into the order the robot travels: the reference is its first pose.
    order = visit.order[reference_visits(len(visit.order), args.reference_every or 0)]
    reference = None if args.reference_every is None else order == visit.order[0]
    q_rad = q_rad[order]
    port = None if port is None else port[order]
    if options is None:
        write_plan(args.out, q_rad, robot, port_names, port, reference)
    else:
        write_atomic(args.out, plan_module(robot, q_rad, options, port_names, port))
    unit = "s at the rated joint speeds" if robot.velocity_rad_s is not None \
        else "rad of the joint that moves most"
    revisits = "" if reference is None else (
        f"; {int(reference.sum()) - 1} revisits of the first pose, {len(order)} rows")
    return (f"visiting order: a round trip from home of {visit.travel_s:.1f} {unit} (the "
            f"design's order: {visit.given_s:.1f}){revisits}")


def _sampler(args: argparse.Namespace) -> SamplerFactory:
    """Candidates the twin can measure, or (--joint-limits-only) any within the limits."""
    from twin.design.planning import joint_limit_sampler

    if not args.feasible:
        return joint_limit_sampler
    from twin.sim.poses import feasible_sampler

    return feasible_sampler


def _model(args: argparse.Namespace, robot: RobotModel, rig: Rig) -> Model:
    """The model the calibration will fit, as the flags say (read as `twin calibrate` reads
    them)."""
    from twin.calibration.settings import CalibrationSettings
    from twin.calibration.setup import make_model
    from twin.cli.inputs import settings_from_flags
    from twin.units import mm_to_m

    settings = settings_from_flags(args, CalibrationSettings(), float(mm_to_m(args.sigma)), 0.0)
    return make_model(robot, rig, settings=settings)


def _check_poses(args: argparse.Namespace, model: Model, stations: int, per: str) -> None:
    """At least as many poses as unknowns, and no more than the candidates."""
    if not model.n_params <= args.poses <= args.candidates * stations:
        raise InputError(f"{args.poses} poses from {args.candidates} candidates{per}",
                         f"at least {model.n_params} poses (the unknowns) and no more than "
                         "the candidates", source="--poses")


def _sigma(args: argparse.Namespace) -> str:
    """The noise the bound is computed at, as `twin identify` shows it."""
    from twin.report.display import SIGNIFICANT, mm
    from twin.units import mm_to_m

    return mm(mm_to_m(args.sigma), significant=SIGNIFICANT)


def _ports_report(args: argparse.Namespace, robot: RobotModel, model: Model,
                  ports_m: NDArray[np.float64], plan: PortPlan) -> str:
    from twin.analysis.workspace import WORKSPACE_POSES
    from twin.report.display import AS_GIVEN, mm, mm_values

    choice, chosen = plan.choice, plan.choice.plans[plan.choice.best]
    lines = []
    if len(ports_m) > 1:
        lines.append("port candidates [mm]        predicted flange RMS [mm]")
        for k, (port, rms) in enumerate(zip(ports_m, choice.flange_rms_m, strict=True)):
            text = mm_values(port, significant=AS_GIVEN)
            lines.append(f"  ({text}){'':<{max(1, 24 - len(text))}}{mm(rms, unit=False)}"
                         + ("   <- chosen" if k == choice.best else ""))
    port_text = mm_values(plan.port_m, significant=AS_GIVEN)
    lines += [
        f"{robot.name}: {args.poses} D-optimal poses of {args.candidates} "
        f"{'feasible ' if args.feasible else ''}candidates "
        f"({chosen.selection.exchanges} exchanges), port ({port_text}) mm, "
        f"{chosen.base_mask.sum()} base parameters of {model.n_params} unknowns",
        *_score_lines(plan.planned, plan.random),
        f"  (base-parameter columns in SI; flange RMS: Cramér–Rao at σ = {_sigma(args)} "
        f"over {WORKSPACE_POSES} workspace poses; random: {args.poses} poses drawn with the "
        "same seed and constraints)",
        f"plan: {args.out}",
    ]
    return "\n".join(lines)


def _stations_report(args: argparse.Namespace, robot: RobotModel, model: Model, rig: Rig,
                     plan: StationsPlan) -> str:
    import numpy as np

    from twin.analysis.workspace import WORKSPACE_POSES

    used = np.bincount(plan.port, minlength=len(rig.ports_m))
    return "\n".join([
        f"{robot.name}: {args.poses} D-optimal (pose, station) pairs of "
        f"{args.candidates} {'feasible ' if args.feasible else ''}candidates per station "
        f"({plan.exchanges} exchanges), {plan.base_parameters} base parameters of "
        f"{model.n_params} unknowns",
        "  stations: " + ", ".join(f"{name} {int(count)} poses" for name, count
                                   in zip(rig.port_names, used, strict=True)),
        *_score_lines(plan.planned, plan.random),
        f"  (base-parameter columns in SI; flange RMS: Cramér–Rao at σ = {_sigma(args)} "
        f"over {WORKSPACE_POSES} workspace poses, modulo what the data cannot see; random: "
        f"{args.poses} poses shared evenly between the stations, drawn with the same seed and "
        "constraints)",
        f"plan: {args.out} (column port: the station of each pose)",
    ])


def _score_lines(planned: DesignScore, drawn: DesignScore) -> list[str]:
    return ["  poses           O1         O3         O4  condition  flange RMS [mm]",
            _score_row("planned", planned), _score_row("random", drawn)]
