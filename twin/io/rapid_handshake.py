"""The RAPID plan module with the capture handshake: the robot runs the plan and waits at each
pose until `twin capture` has the pose on disk.

The module (default name :data:`MODULE`, task :data:`TASK`) declares three persistent symbols,
the whole handshake; twin reads and writes them over Robot Web Services and nothing else of the
program:

========== ========= =============== ===================================================
symbol     type      who writes it   meaning
========== ========= =============== ===================================================
twin_pose  PERS num  the module      the plan pose the robot stands at, 1..N (0: none yet)
twin_ready PERS bool the module      TRUE once the robot stands still at ``twin_pose``
twin_ack   PERS num  twin (RWS)      the last pose twin has on disk
========== ========= =============== ===================================================

The program goes through the plan in order (pose K from pose K − 1, as twin's backlash model
takes it), each move ``MoveAbsJ … fine`` then ``WaitRob \\ZeroSpeed``; it sets ``twin_pose``
before ``twin_ready`` and waits for ``twin_ack = twin_pose`` before it moves on. Started from
main it resets ``twin_ack`` and runs the whole plan again: twin acknowledges at once the poses it
already has, so a capture resumed after any crash (of twin, of the controller) loses and repeats
nothing. A pose is waiting for twin while ``twin_ready`` is TRUE and ``twin_ack`` differs from
``twin_pose``.

Joint values: degrees, robot axes ``rax_1..rax_6`` (an arm of fewer joints leaves the rest at
0), a 7th joint in the first external axis ``eax_a`` (as ABB's 7-axis arms report it); unused
external axes are 9E+09, RAPID's "no axis".

:func:`read_handshake_module` reads the plan back from such a module (what the virtual
controller runs).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from twin.errors import InputError
from twin.io.paths import read_text
from twin.io.rapid import NO_AXIS
from twin.units import deg_to_rad, rad_to_deg

MODULE = "TwinPlan"
"""The module's default name; its file is ``TwinPlan.mod``."""
TASK = "T_ROB1"
"""The motion task the module is loaded into."""
POSE_SYMBOL, READY_SYMBOL, ACK_SYMBOL = "twin_pose", "twin_ready", "twin_ack"
PLAN_SYMBOL = "twin_plan"
NO_AXIS_ABOVE = 1e9
"""A value beyond this is "no axis" (9E+09 as the controller prints it, 8.999999e+09…)."""
ROBOT_AXES, EXTERNAL_AXES = 6, 6
DECIMALS = 6
"""Decimals of a joint angle in degrees (1e-6 deg: 0.01 µm at 1 m)."""
MAX_MODULE_POSES = 10000
"""Most poses a module holds (a RAPID array of this many jointtargets loads on an IRC5)."""


class HandshakeModule(NamedTuple):
    """A plan module read back."""

    name: str
    """The module's name."""
    q_rad: NDArray[np.float64]
    """The plan, shape (N, n), rad."""


def axes_deg(q_deg: NDArray[np.float64]) -> NDArray[np.float64]:
    """A jointtarget's 12 values (robot axes, then external axes) of joint angles in degrees,
    shape (..., 12): joints 1..6 in rax, a 7th in eax_a."""
    q = np.asarray(q_deg, dtype=np.float64)
    n = q.shape[-1]
    axes = np.zeros((*q.shape[:-1], ROBOT_AXES + EXTERNAL_AXES))
    axes[..., ROBOT_AXES:] = NO_AXIS
    axes[..., :min(n, ROBOT_AXES)] = q[..., :ROBOT_AXES]
    if n > ROBOT_AXES:
        axes[..., ROBOT_AXES:n] = q[..., ROBOT_AXES:]
    return axes


def joints_deg(axes: NDArray[np.float64], n_joints: int) -> NDArray[np.float64]:
    """The joint angles, degrees, shape (..., n_joints), of jointtarget values (..., 12)."""
    values = np.asarray(axes, dtype=np.float64)
    if n_joints <= ROBOT_AXES:
        return values[..., :n_joints]
    return np.concatenate([values[..., :ROBOT_AXES],
                           values[..., ROBOT_AXES:ROBOT_AXES + n_joints - ROBOT_AXES]], axis=-1)


def _number(value: float) -> str:
    return "9E+09" if value > NO_AXIS_ABOVE else f"{value:.{DECIMALS}f}"


def module_text(q_rad: NDArray[np.float64], *, name: str = MODULE, speed: str = "v100",
                source: str = "") -> str:
    """The RAPID module of a plan (see the module docstring).

    Args:
        q_rad: The plan, shape (N, n), rad.
        name: The module's name.
        speed: The speeddata of every move (a predefined one, ``v5`` … ``v7000``).
        source: Where the plan came from, for the module's header comment.
    """
    q = np.asarray(q_rad, dtype=np.float64)
    if q.ndim != 2 or not 1 <= len(q) <= MAX_MODULE_POSES:
        raise ValueError(f"q_rad: shape {q.shape}, expected (N, n) with "
                         f"1 <= N <= {MAX_MODULE_POSES}")
    if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]{0,31}", name):
        raise InputError(f"{name!r}", "a RAPID identifier (a letter, then letters, digits "
                         "or _, at most 32)", where="module name")
    if not re.fullmatch(r"v[0-9]+", speed):
        raise InputError(f"{speed!r}", "a predefined speeddata such as v100", where="speed")
    targets = [
        "[[" + ",".join(_number(v) for v in row[:ROBOT_AXES]) + "],["
        + ",".join(_number(v) for v in row[ROBOT_AXES:]) + "]]"
        for row in axes_deg(rad_to_deg(q))
    ]
    plan = ",\n        ".join(targets)
    n = len(q)
    return f"""MODULE {name}
    ! Written by twin{f' from {source}' if source else ''}: {n} poses of a {q.shape[1]}-joint arm.
    ! The capture handshake (twin reads twin_pose and twin_ready, writes twin_ack, over RWS):
    !   twin_pose   the plan pose the robot stands at, 1..{n} (0: none yet)
    !   twin_ready  TRUE once the robot stands still at twin_pose
    !   twin_ack    the last pose twin has on disk; the robot waits for it at every pose
    PERS num {POSE_SYMBOL} := 0;
    PERS bool {READY_SYMBOL} := FALSE;
    PERS num {ACK_SYMBOL} := 0;
    CONST jointtarget {PLAN_SYMBOL}{{{n}}} := [
        {plan}];

    PROC main()
        {READY_SYMBOL} := FALSE;
        {ACK_SYMBOL} := 0;
        FOR k FROM 1 TO {n} DO
            MoveAbsJ {PLAN_SYMBOL}{{k}}, {speed}, fine, tool0;
            WaitRob \\ZeroSpeed;
            {POSE_SYMBOL} := k;
            {READY_SYMBOL} := TRUE;
            WaitUntil {ACK_SYMBOL} = k;
            {READY_SYMBOL} := FALSE;
        ENDFOR
        Stop;
    ENDPROC
ENDMODULE
"""


_PLAN = re.compile(r"CONST\s+jointtarget\s+" + PLAN_SYMBOL + r"\s*\{\s*(\d+)\s*\}\s*:=\s*"
                   r"\[(.*?)\]\s*;", re.S | re.I)
_NAME = re.compile(r"^\s*MODULE\s+([A-Za-z][A-Za-z0-9_]*)", re.M | re.I)
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_TARGET = re.compile(r"\[\s*\[([^\[\]]*)\]\s*,\s*\[([^\[\]]*)\]\s*\]")


def read_handshake_module(path: str | Path, n_joints: int) -> HandshakeModule:
    """The plan of a handshake module file (:func:`module_text`'s, or one written to it).

    Raises:
        InputError: if the file has no ``twin_plan`` array of jointtargets, or its values are
            not numbers.
    """
    what = "a RAPID plan module with the twin handshake"
    text = read_text(path, what)
    name, plan = _NAME.search(text), _PLAN.search(text)
    if name is None or plan is None:
        raise InputError("no MODULE with a CONST jointtarget twin_plan{N}", what, source=path)
    rows = []
    for robax, extax in _TARGET.findall(plan[2]):
        fields = [f.strip() for f in f"{robax},{extax}".split(",")]
        if len(fields) != ROBOT_AXES + EXTERNAL_AXES or not all(
                re.fullmatch(_NUMBER, f) for f in fields):
            raise InputError(f"a jointtarget [{robax}],[{extax}]", "6 robot and 6 external "
                             "axis values", source=path, where=PLAN_SYMBOL)
        rows.append([float(f) for f in fields])
    if len(rows) != int(plan[1]) or not rows:
        raise InputError(f"{len(rows)} jointtargets in {PLAN_SYMBOL}{{{plan[1]}}}",
                         "as many as the array declares, at least one", source=path)
    return HandshakeModule(name[1], deg_to_rad(joints_deg(np.array(rows), n_joints)))
