"""Program filtering: a RAPID module's targets rewritten so that the real robot goes where the
nominal one would have (`twin compensate --rapid IN.mod --out OUT.mod`).

- A ``jointtarget`` (``MoveAbsJ``) holds joint angles: it is compensated as a program row
  (:func:`twin.compensation.joints.compensate_program_rows`): the identified robot's flange at
  the new angles is the nominal flange at the old ones, position and orientation.
- A ``robtarget`` holds the TCP's pose in a work object with a tool, and the axis configuration
  the controller is to reach it on. Its tool and work object are those of the motion
  instructions that go to it (each must use one of each: a target moved to with two tools is
  two targets, and is left as it is), read from the module's ``tooldata`` and ``wobjdata`` or
  given as flags; ``tool0`` and ``wobj0`` are the controller's own. The pose is turned into the
  flange pose (:mod:`twin.compensation.poses`), the controller's joints for it found on the
  nominal model on the target's configuration (cf1, cf4, cf6, cfx), those joints compensated as
  a program row, and the target rewritten as what the **nominal** model (the controller's) puts
  the TCP at with the corrected joints: given it, the controller commands the corrected joints,
  and the real robot lands on the original target. The configuration is kept: cfx must stay the
  same (else the correction crosses a singularity, and the target is left); cf1, cf4, cf6 follow
  the corrected joints where one crosses a quarter turn (a correction of a few hundredths of a
  degree at 90°), and such targets are named. External axes are never touched.

Only the numbers of corrected targets change (:func:`twin.io.rapid.rewrite`): the position to
1e-6 mm, the quaternion to 1e-9, joint angles to 1e-6 degree (the controller's ``num`` is a 32-bit
float: some 7 significant digits are kept). Targets that cannot be corrected — beyond the joint
limits, unreachable, at a singularity, without a known tool or work object, on a stationary tool
or a moving work object, declared by an expression — are left exactly as written and listed.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from twin.arrays import Array
from twin.compensation.configuration import configuration
from twin.compensation.ik import STATUS_OK, STATUS_SINGULAR, STATUS_UNREACHABLE
from twin.compensation.joints import compensate_pose_rows, compensate_program_rows
from twin.compensation.poses import flange_targets, pose_matrices, pose_quaternions, tcp_targets
from twin.errors import InputError
from twin.io.pose_tables import INTEGER_TOLERANCE
from twin.io.rapid import (
    Aggregate,
    Declaration,
    JointTarget,
    Module,
    Number,
    RobTarget,
    Token,
    Value,
    format_number,
    jointtarget,
    parse_literal,
    refuse_prismatic,
    rewrite,
    robtarget,
    tooldata,
    wobjdata,
)
from twin.model import Model
from twin.robot import RobotModel
from twin.units import deg_to_rad, m_to_mm, mm_to_m, rad_to_deg

MM_DECIMALS = 6
QUATERNION_DECIMALS = 9
DEG_DECIMALS = 6
BUILTIN_TOOL = "tool0"
BUILTIN_WOBJ = "wobj0"
STATUS_CORRECTED = "corrected"
STATUS_UNKNOWN_FRAME = "unknown_frame"
STATUS_UNSUPPORTED = "unsupported"

Key = tuple[str | None, str]
"""A declaration's routine (lower case, None at module level) and name (lower case)."""


class Use(NamedTuple):
    """A motion instruction that goes to a target."""

    tool: str | None
    """The tool it names, or None (MoveAbsJ's does not matter)."""
    wobj: str | None
    """Its ``\\WObj``, or None (wobj0)."""
    line: int
    routine: str | None


class Target(NamedTuple):
    """A target of the module: declared (a name, an array element) or inline in a move."""

    name: str
    line: int
    kind: str
    """``robtarget`` or ``jointtarget``."""
    literal: RobTarget | JointTarget
    uses: tuple[Use, ...]
    routine: str | None
    """Where it is declared (its tools are looked up from there when no move names one)."""


class TargetRow(NamedTuple):
    """What was done with one target."""

    name: str
    line: int
    kind: str
    status: str
    """``corrected``, or why not: ``unreachable``, ``joint_limit``, ``singular``,
    ``unknown_frame``, ``unsupported``."""
    note: str
    change: float
    """The largest change: of a joint angle, degrees (jointtarget), or of the TCP position, mm
    (robtarget); 0 when not corrected."""


class Filtered(NamedTuple):
    """A filtered module: its new text and a row per target, in the module's order."""

    text: str
    rows: tuple[TargetRow, ...]


class TargetFrames(NamedTuple):
    """Tools and work objects given beside the module: by name, ``tool0_T_tcp`` and
    ``base_T_wobj`` (4, 4), m; the ``None`` entries serve targets no motion instruction goes
    to. They win over the module's declarations."""

    tools: Mapping[str | None, Array]
    wobjs: Mapping[str | None, Array]


def _reference(tokens: tuple[Token, ...]) -> str | None:
    """The target a positional argument names: ``p10`` or ``path{2}``; None otherwise."""
    texts = [t.text for t in tokens]
    if len(tokens) == 1 and tokens[0].kind == "name":
        return texts[0]
    if len(tokens) == 4 and tokens[0].kind == "name" and texts[1] == "{" and texts[3] == "}" \
            and tokens[2].kind == "number":
        return f"{texts[0]}{{{int(float(texts[2]))}}}"
    return None


def _declared(module: Module, type_name: str) -> dict[Key, Declaration]:
    return {(d.routine, d.name.lower()): d for d in module.declarations if d.type == type_name}


def _lookup(keys: Mapping[Key, object], routine: str | None, name: str) -> Key | None:
    """The declaration a name in a routine means: the routine's own, else the module's."""
    return next((key for key in ((routine, name.lower()), (None, name.lower())) if key in keys),
                None)


def _elements(declaration: Declaration) -> list[tuple[str, Value]]:
    value = declaration.value
    if value is None:
        return []
    if not declaration.array:
        return [(declaration.name, value)]
    items = value.items if isinstance(value, Aggregate) else ()
    return [(f"{declaration.name}{{{k + 1}}}", item) for k, item in enumerate(items)]


def _parse_target(kind: str, value: Value, source: str, line: int) -> RobTarget | JointTarget:
    try:
        return robtarget(value) if kind == "robtarget" else jointtarget(value)
    except ValueError as exc:
        raise InputError(f"a {kind} literal that is not one ({exc})", f"a {kind} as the RAPID "
                         "reference manual defines it", source=source, where=f"line {line}"
                         ) from None


def find_targets(module: Module) -> list[Target]:
    """Every robtarget and jointtarget of the module with a literal value, and the motion
    instructions that go to each: declared targets in the module's order, then inline ones."""
    declared = {key: d for kind in ("robtarget", "jointtarget")
                for key, d in _declared(module, kind).items()}
    uses: dict[tuple[Key, str], list[Use]] = {}
    inline: list[Target] = []
    for move in module.moves:
        tool = move.argument("tool")
        use = Use(None if tool is None else _reference(tool.tokens), move.wobj, move.line,
                  move.routine)
        kind = "jointtarget" if move.instruction.lower() == "moveabsj" else "robtarget"
        for role in ("cir", "to"):
            argument = move.argument(role)
            if argument is None:
                continue
            if argument.tokens[0].text == "[":
                value, _ = parse_literal(argument.tokens, 0, module.source)
                inline.append(Target(f"inline {move.instruction}", move.line, kind,
                                     _parse_target(kind, value, module.source, move.line),
                                     (use,), move.routine))
                continue
            name = _reference(argument.tokens)
            key = None if name is None else _lookup(declared, move.routine, name.split("{")[0])
            if key is not None and name is not None:
                uses.setdefault((key, name.lower()), []).append(use)
    targets = [Target(name, d.line, d.type, _parse_target(d.type, value, module.source, d.line),
                      tuple(uses.get((key, name.lower()), ())), d.routine)
               for key, d in declared.items() for name, value in _elements(d)]
    return sorted(targets, key=lambda t: t.line) + inline


def _frame_matrix(trans_mm: ArrayLike, quaternion: ArrayLike, source: str, line: int) -> Array:
    try:
        return pose_matrices(mm_to_m(trans_mm), quaternion)[0]
    except ValueError as exc:
        raise InputError(str(exc), "a pose with a unit quaternion", source=source,
                         where=f"line {line}") from None


def _given(frames: Mapping[str | None, Array], name: str | None) -> Array | None:
    """A frame given by flag for a name (RAPID names are not case sensitive), or None."""
    for key, value in frames.items():
        if (key is None) == (name is None) and (key or "").lower() == (name or "").lower():
            return value
    return None


def _tool(module: Module, frames: TargetFrames, use: Use) -> tuple[Array | None, str]:
    """tool0_T_tcp of a use's tool, or None and why not."""
    name = use.tool
    given = _given(frames.tools, name)
    if given is not None:
        return given, ""
    if name is None:
        return None, "no motion instruction goes to it with a tool (give --tool X,Y,Z,…)"
    if name.lower() == BUILTIN_TOOL:
        return np.eye(4), ""
    table = _declared(module, "tooldata")
    key = _lookup(table, use.routine, name)
    value = None if key is None else table[key].value
    if key is None or value is None:
        return None, f"tool {name} is not declared in the module (give --tool {name}=X,Y,Z,…)"
    try:
        tool = tooldata(value)
    except ValueError as exc:
        raise InputError(f"tooldata {name} that is not one ({exc})", "a tooldata literal",
                         source=module.source, where=f"line {table[key].line}") from None
    if not tool.robhold:
        return None, f"tool {name} is stationary (robhold FALSE): not supported"
    return _frame_matrix(tool.tframe.trans_mm, tool.tframe.quaternion, module.source,
                         table[key].line), ""


def _wobj(module: Module, frames: TargetFrames, use: Use) -> tuple[Array | None, str]:
    """base_T_wobj of a use's work object (wobj0 when it names none), or None and why not."""
    name = use.wobj
    given = _given(frames.wobjs, name)
    if given is not None:
        return given, ""
    if name is None or name.lower() == BUILTIN_WOBJ:
        return np.eye(4), ""
    table = _declared(module, "wobjdata")
    found = _lookup(table, use.routine, name)
    value = None if found is None else table[found].value
    if found is None or value is None:
        return None, (f"work object {name} is not declared in the module (give --wobj "
                      f"{name}=X,Y,Z,…)")
    try:
        wobj = wobjdata(value)
    except ValueError as exc:
        raise InputError(f"wobjdata {name} that is not one ({exc})", "a wobjdata literal",
                         source=module.source, where=f"line {table[found].line}") from None
    if wobj.robhold or not wobj.ufprog or wobj.ufmec:
        return None, (f"work object {name} is held by the robot or moved by a mechanical unit: "
                      "not supported")
    line = table[found].line
    return (_frame_matrix(wobj.uframe.trans_mm, wobj.uframe.quaternion, module.source, line)
            @ _frame_matrix(wobj.oframe.trans_mm, wobj.oframe.quaternion, module.source, line)), ""


def _frames_of(module: Module, frames: TargetFrames, target: Target
               ) -> tuple[Array | None, Array | None, str]:
    """A robtarget's tool and work object, or why it has none."""
    distinct = {((u.tool or "").lower(), (u.wobj or BUILTIN_WOBJ).lower()) for u in target.uses}
    if len(distinct) > 1:
        lines = ", ".join(str(u.line) for u in target.uses)
        return None, None, (f"moved to with several tools or work objects (lines {lines}): "
                            "one target cannot be corrected for two")
    use = target.uses[0] if target.uses else Use(None, None, target.line, target.routine)
    tool, why = _tool(module, frames, use)
    wobj, why_wobj = _wobj(module, frames, use)
    return tool, wobj, why or why_wobj


def _changed(numbers: tuple[Number, ...], values: ArrayLike, decimals: int
             ) -> list[tuple[Number, str]]:
    """The numbers whose rounded new value differs from what is written, with their text."""
    changes = []
    for number, value in zip(numbers, np.asarray(values, dtype=np.float64), strict=True):
        # A number that rounds to what is written stays as written (its bytes too).
        if abs(float(value) - number.value) >= 0.5 * 10.0 ** -decimals:
            changes.append((number, format_number(float(value), decimals)))
    return changes


def _joint_rows(model: Model, x: ArrayLike, nominal: RobotModel, targets: list[Target]
                ) -> tuple[list[TargetRow], list[tuple[Number, str]]]:
    """Jointtargets compensated as program rows."""
    if not targets:
        return [], []
    q_deg = np.array([t.literal.robax_deg for t in targets  # type: ignore[union-attr]
                      ])
    q = deg_to_rad(q_deg)
    inside = np.all((q >= nominal.lower_rad) & (q <= nominal.upper_rad), axis=1)
    solved = compensate_program_rows(model, x, nominal, np.where(inside[:, None], q, 0.0)).solved
    rows, changes = [], []
    for k, target in enumerate(targets):
        literal = target.literal
        assert isinstance(literal, JointTarget)
        if not inside[k]:
            rows.append(TargetRow(target.name, target.line, target.kind, "joint_limit",
                                  "its own angles are outside the robot's joint limits", 0.0))
            continue
        if solved.status[k] != STATUS_OK:
            why = "it lies next to a singularity, where the correction would swing joints by " \
                "degrees" if solved.status[k] == STATUS_SINGULAR \
                else "the identified robot cannot be compensated there"
            rows.append(TargetRow(target.name, target.line, target.kind, str(solved.status[k]),
                                  why, 0.0))
            continue
        corrected = rad_to_deg(solved.q_rad[k])
        changes += _changed(literal.robax, corrected, DEG_DECIMALS)
        rows.append(TargetRow(target.name, target.line, target.kind, STATUS_CORRECTED, "",
                              float(np.abs(corrected - q_deg[k]).max())))
    return rows, changes


class _Prepared(NamedTuple):
    """The robtargets that have a tool and work object, as arrays."""

    targets: list[Target]
    tcp_in_wobj: Array
    """The targets, (m, 4, 4), m."""
    wobj_in_base: Array
    tcp_in_tool0: Array
    conf: Array


def _prepare(module: Module, frames: TargetFrames, targets: list[Target]
             ) -> tuple[_Prepared, list[TargetRow]]:
    kept, rows = [], []
    poses, wobjs, tools, confs = [], [], [], []
    for target in targets:
        literal = target.literal
        assert isinstance(literal, RobTarget)
        tool, wobj, why = _frames_of(module, frames, target)
        conf = literal.configuration
        if tool is None or wobj is None:
            status = STATUS_UNKNOWN_FRAME if "give" in why else STATUS_UNSUPPORTED
            rows.append(TargetRow(target.name, target.line, target.kind, status, why, 0.0))
            continue
        if np.any(np.abs(conf - np.round(conf)) > INTEGER_TOLERANCE):
            rows.append(TargetRow(target.name, target.line, target.kind, STATUS_UNSUPPORTED,
                                  "its robconf is not four integers", 0.0))
            continue
        kept.append(target)
        poses.append(_frame_matrix(literal.trans_mm, literal.quaternion, module.source,
                                   target.line))
        wobjs.append(wobj)
        tools.append(tool)
        confs.append(np.round(conf).astype(np.int64))
    empty = np.zeros((0, 4, 4))
    return _Prepared(kept, np.array(poses) if poses else empty, np.array(wobjs) if wobjs
                     else empty, np.array(tools) if tools else empty,
                     np.array(confs) if confs else np.zeros((0, 4), dtype=np.int64)), rows


def _robtarget_rows(module: Module, model: Model, x: ArrayLike, nominal: RobotModel,
                    flange_T_tool0: Array, frames: TargetFrames, targets: list[Target],
                    rng: np.random.Generator
                    ) -> tuple[list[TargetRow], list[tuple[Number, str]]]:
    """Robtargets: flange poses, the nominal joints on their configuration, compensated, and
    written back as the nominal model's TCP pose at the corrected joints."""
    prepared, rows = _prepare(module, frames, targets)
    if not prepared.targets:
        return rows, []
    base_T_flange = flange_targets(prepared.tcp_in_wobj, prepared.wobj_in_base,
                                   prepared.tcp_in_tool0, flange_T_tool0)
    solved = compensate_pose_rows(model, x, nominal, base_T_flange, rng, prepared.conf)
    q = solved.ordered.solved.q_rad
    reached = configuration(nominal, q)
    tcp = tcp_targets(nominal.flange_transforms(q), prepared.wobj_in_base, prepared.tcp_in_tool0,
                      flange_T_tool0)
    changes: list[tuple[Number, str]] = []
    for k, target in enumerate(prepared.targets):
        literal = target.literal
        assert isinstance(literal, RobTarget)
        row = _pose_row(target, literal, solved.nominal.ok[k], str(solved.ordered.solved.status[k]),
                        prepared.conf[k], reached[k])
        if row.status == STATUS_CORRECTED:
            trans_mm, quaternion = pose_quaternions(tcp[k:k + 1], literal.quaternion)
            trans_mm = m_to_mm(trans_mm[0])
            changes += _changed(literal.trans, trans_mm, MM_DECIMALS)
            changes += _changed(literal.rot, quaternion[0], QUATERNION_DECIMALS)
            changes += _changed(literal.robconf[:3], reached[k][:3], 0)
            row = row._replace(change=float(np.linalg.norm(trans_mm - literal.trans_mm)))
        rows.append(row)
    return rows, changes


def _pose_row(target: Target, literal: RobTarget, nominal_ok: bool, status: str,
              wanted: Array, reached: Array) -> TargetRow:
    """A robtarget's row: corrected, or why not."""
    conf = "[" + ",".join(str(int(v)) for v in wanted) + "]"
    if not nominal_ok:
        return TargetRow(target.name, target.line, target.kind, STATUS_UNREACHABLE,
                         f"no joints on configuration {conf} within the limits reach it on the "
                         "nominal model (out of reach, or at a singularity)", 0.0)
    if status != STATUS_OK:
        return TargetRow(target.name, target.line, target.kind, status,
                         "the identified robot cannot be compensated there", 0.0)
    if reached[3] != wanted[3]:
        return TargetRow(target.name, target.line, target.kind, STATUS_SINGULAR,
                         f"the correction crosses a singularity (cfx {wanted[3]} becomes "
                         f"{reached[3]})", 0.0)
    note = ""
    if np.any(reached[:3] != wanted[:3]):
        note = (f"robconf {conf} becomes [{','.join(str(int(v)) for v in reached)}]: a "
                "corrected joint crosses a quarter turn")
    return TargetRow(target.name, target.line, target.kind, STATUS_CORRECTED, note, 0.0)


def filter_module(module: Module, model: Model, x: ArrayLike, nominal: RobotModel,
                  flange_T_tool0: Array | None, frames: TargetFrames, rng: np.random.Generator
                  ) -> Filtered:
    """Every target of a module compensated for the identified model (see the module
    docstring).

    Args:
        module: The parsed module (:func:`twin.io.rapid.read_module`).
        model: The identified measurement model; without backlash (a module does not say from
            which side each joint comes to a target).
        x: Its unknowns, shape (p,).
        nominal: The nominal robot, the controller's, SI; 6 joints.
        flange_T_tool0: The controller's tool0 in twin's flange frame, (4, 4)
            (:func:`twin.compensation.poses.controller_tool0`); None refuses robtargets.
        frames: Tools and work objects given beside the module.
        rng: Generator of the nominal IK's random starts.

    Raises:
        InputError: for a module with robtargets and no ``flange_T_tool0``, a target literal
            that does not parse, or a result with backlash.
    """
    refuse_prismatic(nominal.joint_names, nominal.prismatic, module.source)
    if model.needs_approach:
        raise InputError("a result with backlash", "a result without backlash for a RAPID "
                         "module (it does not say from which side each joint comes to a "
                         "target): or compensate its joints with --joints and approach1..6 "
                         "columns", source=module.source)
    targets = find_targets(module)
    joints = [t for t in targets if t.kind == "jointtarget"]
    poses = [t for t in targets if t.kind == "robtarget"]
    if poses and flange_T_tool0 is None:
        raise InputError(f"robtargets for {nominal.name}, whose controller flange frame (tool0) "
                         "twin does not know", "--tool0-in-flange X,Y,Z,QW,QX,QY,QZ: the "
                         "controller's tool0 in twin's flange frame (mm, quaternion)",
                         source=module.source)
    joint_rows, joint_changes = _joint_rows(model, x, nominal, joints)
    pose_rows, pose_changes = ([], []) if not poses else _robtarget_rows(
        module, model, x, nominal, flange_T_tool0, frames, poses, rng)  # type: ignore[arg-type]
    order = {(t.name, t.line): k for k, t in enumerate(targets)}
    rows = sorted([*joint_rows, *pose_rows], key=lambda row: order[(row.name, row.line)])
    return Filtered(rewrite(module.text, joint_changes + pose_changes), tuple(rows))


def format_filter_rows(rows: tuple[TargetRow, ...]) -> str:
    """The summary of a filtered module: counts, the largest change, every target left as it
    was (with why) and every corrected one with a note."""
    corrected = [row for row in rows if row.status == STATUS_CORRECTED]
    left = [row for row in rows if row.status != STATUS_CORRECTED]
    lines = [f"{len(rows)} targets: {len(corrected)} corrected, {len(left)} left as written"]
    for kind, unit in (("jointtarget", "deg"), ("robtarget", "mm")):
        changes = [row.change for row in corrected if row.kind == kind]
        if changes:
            lines.append(f"  {kind}s: largest change {max(changes):.4f} {unit}, mean "
                         f"{float(np.mean(changes)):.4f} {unit}")
    lines += [f"  left: {row.name} (line {row.line}): {row.status}: {row.note}" for row in left]
    lines += [f"  note: {row.name} (line {row.line}): {row.note}" for row in corrected
              if row.note]
    return "\n".join(lines)
