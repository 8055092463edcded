"""A pose plan as a RAPID module the controller runs (`twin plan … --out plan.mod`).

The module drives the robot through the planned poses with ``MoveAbsJ`` to ``jointtarget``\\ s
(joint moves, ``fine`` zones: the robot stops at each pose), waits for it to settle, and tells
a capture where it is through two persistent variables. The handshake, which `twin capture`
over Robot Web Services follows (RWS reads and writes PERS data by name, ``T_ROB1/TwinPlan/…``):

1. At start the robot sets ``twin_ready := FALSE`` and ``twin_pose := 0``, then moves to
   ``twin_home``.
2. For pose k = 1 … ``twin_count``: ``MoveAbsJ twin_poses{k}`` with ``fine``; ``WaitTime
   twin_settle`` (s); ``twin_pose := k``; ``twin_ready := TRUE``; then ``WaitUntil twin_ready =
   FALSE``. The capture, seeing ``twin_ready`` TRUE, reads the encoder for pose ``twin_pose``
   (and may read the robot's joints), then writes ``twin_ready := FALSE``: the robot moves on.
3. After the last pose the robot returns to ``twin_home`` and sets ``twin_pose :=
   twin_count + 1`` (finished; ``twin_ready`` stays FALSE).

With an encoder moved between stations the module stops (``Stop``) before the first pose of each
new station, after ``TPWrite`` naming it: move the encoder, then press start.

Safe approach: the robot goes to ``twin_home`` first and last (by default every joint at 0 but
the wrist's fifth at 30°, :func:`twin.compensation.ik.home_pose`), joint moves at the speed
asked for (``v100`` by default), poses in the plan's order (`twin plan` writes a short tour
from home, :mod:`twin.design.order`; a capture records each joint's approach direction whatever
the order). The poses and home are checked against the robot's joint limits before anything is
written; the moves *between* poses are joint interpolations the planner did not check for
collisions: run the module first in RobotStudio or at reduced speed.

Angles are written to 1e-6 degree, as in the plan CSV: the module parses back to exactly the
plan's numbers (the controller's ``num``, a 32-bit float, then keeps some 7 digits).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from twin.arrays import Array
from twin.choices import DEFAULT_SETTLE_S, DEFAULT_SPEED
from twin.errors import InputError
from twin.io.rapid import format_number, refuse_prismatic
from twin.robot import RobotModel
from twin.units import FILE_DEG_DECIMALS, rad_to_deg

MODULE_NAME = "TwinPlan"
POSE_SYMBOL = "twin_pose"
READY_SYMBOL = "twin_ready"
SPEEDS = ("v5", "v10", "v20", "v30", "v40", "v50", "v60", "v80", "v100", "v150", "v200", "v300",
          "v400", "v500", "v600", "v800", "v1000", "v1500", "v2000", "v2500", "v3000", "v4000",
          "v5000", "v6000", "v7000", "vmax")
"""ABB's predefined speeddata."""
MAX_NAME_CHARS = 32
"""RAPID identifiers are at most 32 characters."""
_IDENTIFIER = re.compile(r"[A-Za-z][A-Za-z0-9_]*")
NO_AXES = "[9E9,9E9,9E9,9E9,9E9,9E9]"


class PlanOptions(NamedTuple):
    """How the module moves: speed (a predefined speeddata), tool and work object (names the
    controller's task declares), the settle time before each reading, s, and home (rad)."""

    speed: str = DEFAULT_SPEED
    tool: str = "tool0"
    wobj: str = "wobj0"
    settle_s: float = DEFAULT_SETTLE_S
    home_rad: Array | None = None


def check_identifier(name: str, flag: str) -> str:
    """A RAPID data name, or an InputError naming the flag."""
    if not _IDENTIFIER.fullmatch(name) or len(name) > MAX_NAME_CHARS:
        raise InputError(f"{name!r}", f"a RAPID name: a letter, then letters, digits or _, at "
                         f"most {MAX_NAME_CHARS} characters", source=flag)
    return name


def _jointtarget(q_deg: Array) -> str:
    return "[[" + ",".join(format_number(v, FILE_DEG_DECIMALS) for v in q_deg) + "]," \
        + NO_AXES + "]"


def _check_limits(robot: RobotModel, q_deg: Array, what: str) -> None:
    """Refuse angles (rounded as written) beyond the robot's limits."""
    lower, upper = rad_to_deg(robot.lower_rad), rad_to_deg(robot.upper_rad)
    outside = np.argwhere((q_deg < lower) | (q_deg > upper))
    if outside.size:
        row, joint = outside[0]
        raise InputError(f"{what} {row + 1}: joint {joint + 1} at {q_deg[row, joint]:g} deg",
                         f"within [{lower[joint]:g}, {upper[joint]:g}] deg ({robot.name}): "
                         "nothing was written")


def plan_module(robot: RobotModel, q_rad: Array, options: PlanOptions,
                stations: Sequence[str] = (), station: NDArray[np.intp] | None = None) -> str:
    """The RAPID module of a plan (see the module docstring).

    Args:
        robot: The robot, 6 joints (a RAPID jointtarget holds six axes).
        q_rad: The plan, shape (m, 6), rad, in the order to visit.
        options: Speed, tool, work object, settle time, home.
        stations: The encoder's station names, for a plan over several.
        station: Each pose's station, index into ``stations``, shape (m,).

    Raises:
        InputError: for a robot that is not 6-axis, a pose or home beyond the joint limits, a
            speed that is not a predefined one.
    """
    if robot.n_joints != 6:
        raise InputError(f"a robot of {robot.n_joints} joints", "a 6-axis robot for a RAPID "
                         "module (a jointtarget holds six axes)", source="--out")
    refuse_prismatic(robot.joint_names, robot.prismatic, "--out")
    if options.speed not in SPEEDS:
        raise InputError(f"{options.speed!r}", "one of ABB's speeddata: " + ", ".join(SPEEDS),
                         source="--speed")
    from twin.compensation.ik import home_pose

    q_deg = np.array([[float(format_number(v, FILE_DEG_DECIMALS)) for v in row]
                      for row in rad_to_deg(q_rad)]).reshape(-1, robot.n_joints)
    home_deg = rad_to_deg(home_pose(robot) if options.home_rad is None else options.home_rad)
    _check_limits(robot, q_deg, "pose")
    _check_limits(robot, home_deg[None, :], "home")
    m = len(q_deg)
    move = f"{options.speed}, fine, {options.tool}\\WObj:={options.wobj}"
    lines = [
        f"MODULE {MODULE_NAME}",
        f"  ! {m} poses of {robot.name}, written by twin plan: MoveAbsJ to each, fine, settle,",
        f"  ! then {POSE_SYMBOL} := k and {READY_SYMBOL} := TRUE until the capture sets it FALSE",
        "  ! (handshake: twin/io/rapid_plan.py, docs/compensation.md). Joint moves between",
        "  ! poses are not collision-checked: run it first in RobotStudio or at low speed.",
        f"  PERS num {POSE_SYMBOL} := 0;",
        f"  PERS bool {READY_SYMBOL} := FALSE;",
        f"  CONST num twin_count := {m};",
        f"  CONST num twin_settle := {format_number(options.settle_s, 3)};",
        f"  CONST jointtarget twin_home := {_jointtarget(home_deg)};",
        f"  CONST jointtarget twin_poses{{{m}}} := [",
        *[f"    {_jointtarget(row)}{',' if k < m - 1 else ''}" for k, row in enumerate(q_deg)],
        "  ];",
    ]
    if station is not None:
        names = ",".join(f'"{stations[s]}"' for s in station)
        lines.append(f"  CONST string twin_station{{{m}}} := [{names}];")
    lines += [
        "",
        "  PROC main()",
        *(['    VAR string station := "";'] if station is not None else []),
        f"    {READY_SYMBOL} := FALSE;",
        f"    {POSE_SYMBOL} := 0;",
        f"    MoveAbsJ twin_home, {move};",
        "    FOR k FROM 1 TO twin_count DO",
    ]
    if station is not None:
        lines += ["      IF twin_station{k} <> station THEN",
                  '        TPWrite "twin: put the encoder at station " + twin_station{k};',
                  "        Stop;",
                  "        station := twin_station{k};",
                  "      ENDIF"]
    lines += [
        f"      MoveAbsJ twin_poses{{k}}, {move};",
        "      WaitTime twin_settle;",
        f"      {POSE_SYMBOL} := k;",
        f"      {READY_SYMBOL} := TRUE;",
        f"      WaitUntil {READY_SYMBOL} = FALSE;",
        "    ENDFOR",
        f"    MoveAbsJ twin_home, {move};",
        f"    {POSE_SYMBOL} := twin_count + 1;",
        "  ENDPROC",
        "ENDMODULE",
    ]
    return "\n".join(lines) + "\n"
