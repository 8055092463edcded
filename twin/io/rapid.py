"""ABB RAPID modules (IRC5 / OmniCore, RAPID reference manual): the targets, tools and work
objects a module declares, the motion instructions that use them, and where each number sits.

A small tokenizer and parser, enough for what a calibration changes in a program:

- **data declarations** ``[LOCAL|TASK] CONST|PERS|VAR type name[{n}] := [...];`` of the types
  ``robtarget`` ``[[x, y, z], [q1, q2, q3, q4], [cf1, cf4, cf6, cfx], [e1, …, e6]]`` (mm; a
  unit quaternion, scalar first; the axis configuration; the external axes, 9E9 for none),
  ``jointtarget`` ``[[a1, …, a6], [e1, …, e6]]`` (degrees), ``tooldata`` ``[robhold, [[x, y, z],
  [q1, …, q4]], [mass, [cog], [aom], ix, iy, iz]]`` (the TCP in tool0) and ``wobjdata``
  ``[robhold, ufprog, ufmec, [[x, y, z], [q1, …, q4]], [[x, y, z], [q1, …, q4]]]`` (user frame,
  then object frame), in a module or inside a routine, single values and one-dimensional arrays;
- **motion instructions** ``MoveJ``, ``MoveL``, ``MoveC``, ``MoveAbsJ`` (and their ``DO`` and
  ``Sync`` forms): the targets they go to (a declared name, an array element ``p{2}`` or an
  inline literal), their tool and their ``\\WObj``.

Every number keeps the place it was read from (character offsets into the text, which is the
file's bytes decoded as Latin-1, one character per byte), so a rewrite replaces only the numbers
it changes and leaves every other byte as it was (:func:`rewrite`). Anything else in the module
is read only to skip it: comments (``!`` to the end of the line), strings, other declarations
and statements.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np

from twin.arrays import Array
from twin.errors import InputError
from twin.io.paths import read_bytes

WHAT = "a RAPID module (.mod)"


def refuse_prismatic(names: Sequence[str], prismatic: Iterable[bool], source: str | Path
                     ) -> None:
    """RAPID's jointtargets hold a robot's axes in degrees; a linear axis (a track, a lift) is
    an external axis in mm, which twin neither reads nor writes: refuse a robot with one.

    Raises:
        InputError: naming the first prismatic joint.
    """
    sliding = [name for name, slides in zip(names, prismatic, strict=True) if slides]
    if sliding:
        raise InputError(f"the prismatic joint {sliding[0]!r}", "a robot of revolute joints "
                         "for RAPID (twin does not write a linear axis as an external axis)",
                         source=source)
ENCODING = "latin-1"
"""Bytes to characters one to one: offsets into the text are offsets into the file."""
NO_AXIS = 9e9
"""An external axis that is not there."""
TARGET_TYPES = ("robtarget", "jointtarget")
FRAME_TYPES = ("tooldata", "wobjdata")
MOVES = {
    # instruction: (roles of the positional arguments), the target roles being "cir" and "to"
    "movej": ("to", "speed", "zone", "tool"), "movel": ("to", "speed", "zone", "tool"),
    "movec": ("cir", "to", "speed", "zone", "tool"),
    "moveabsj": ("to", "speed", "zone", "tool"),
    "movejdo": ("to", "speed", "zone", "tool", "signal", "value"),
    "moveldo": ("to", "speed", "zone", "tool", "signal", "value"),
    "movecdo": ("cir", "to", "speed", "zone", "tool", "signal", "value"),
    "movejsync": ("to", "speed", "zone", "tool", "proc"),
    "movelsync": ("to", "speed", "zone", "tool", "proc"),
    "movecsync": ("cir", "to", "speed", "zone", "tool", "proc"),
}
"""The motion instructions whose targets a compensation rewrites, by lower-case name."""
ROUTINE_STARTS = ("proc", "func", "trap")
ROUTINE_ENDS = ("endproc", "endfunc", "endtrap")
STORAGE = ("const", "pers", "var")

_TOKEN = re.compile(r"""
    (?P<space>[ \t\r\n\f]+)
  | (?P<comment>![^\n]*)
  | (?P<string>"(?:[^"\n]|"")*")
  | (?P<number>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)
  | (?P<name>[A-Za-z][A-Za-z0-9_]*)
  | (?P<op>:=|<>|<=|>=|[\[\]{}(),;\\:+\-*/<>=.%?&|^~'])
""", re.VERBOSE)


class Token(NamedTuple):
    """One token: its kind (``name``, ``number``, ``string``, ``op``), text and place."""

    kind: str
    text: str
    start: int
    end: int
    line: int


class Number(NamedTuple):
    """A number of a literal, with its sign: its value and the characters it spans."""

    value: float
    start: int
    end: int


class Word(NamedTuple):
    """Any other scalar of a literal: TRUE, FALSE, a string, a name."""

    text: str
    start: int
    end: int


class Aggregate(NamedTuple):
    """A bracketed literal ``[a, b, …]`` and the characters it spans."""

    items: tuple[Aggregate | Number | Word, ...]
    start: int
    end: int


Value = Aggregate | Number | Word


class Declaration(NamedTuple):
    """A data declaration with a literal value (an array's value is an aggregate of them)."""

    storage: str
    """``CONST``, ``PERS`` or ``VAR``, upper case."""
    type: str
    """The data type, lower case."""
    name: str
    routine: str | None
    """The routine it is declared in (lower case), or None at module level."""
    value: Value | None
    """The literal, or None when it has no literal value (an expression, no initial value)."""
    array: bool
    line: int


class Argument(NamedTuple):
    """A positional argument of a motion instruction."""

    role: str
    tokens: tuple[Token, ...]


class MoveInstruction(NamedTuple):
    """A motion instruction and what it names."""

    instruction: str
    """As written (``MoveL``)."""
    line: int
    routine: str | None
    arguments: tuple[Argument, ...]
    wobj: str | None
    """The ``\\WObj`` argument's text, or None (wobj0)."""

    def argument(self, role: str) -> Argument | None:
        """The positional argument in ``role`` (``to``, ``cir``, ``tool``), if written."""
        return next((a for a in self.arguments if a.role == role), None)


class Module(NamedTuple):
    """What a module declares and moves to."""

    text: str
    declarations: tuple[Declaration, ...]
    moves: tuple[MoveInstruction, ...]
    tokens: tuple[Token, ...]
    source: str


def tokenize(text: str, source: str | Path) -> list[Token]:
    """The module's tokens, comments and white space left out.

    Raises:
        InputError: at a character no RAPID token starts with (naming its line).
    """
    tokens: list[Token] = []
    position, line = 0, 1
    while position < len(text):
        match = _TOKEN.match(text, position)
        if match is None:
            raise InputError(f"the character {text[position]!r}", WHAT, source=source,
                             where=f"line {line}")
        kind = str(match.lastgroup)
        if kind not in ("space", "comment"):
            tokens.append(Token(kind, match.group(), position, match.end(), line))
        line += match.group().count("\n")
        position = match.end()
    return tokens


def _error(token: Token, found: str, expected: str, source: str) -> InputError:
    return InputError(found, expected, source=source, where=f"line {token.line}")


def parse_literal(tokens: Sequence[Token], index: int, source: str) -> tuple[Value, int]:
    """The literal starting at ``tokens[index]`` and the index after it."""
    token = tokens[index]
    if token.text == "[":
        items: list[Value] = []
        index += 1
        while True:
            if index >= len(tokens):
                raise _error(token, "an aggregate that is not closed", "']'", source)
            if tokens[index].text == "]" and not items:
                return Aggregate((), token.start, tokens[index].end), index + 1
            item, index = parse_literal(tokens, index, source)
            items.append(item)
            if index < len(tokens) and tokens[index].text == ",":
                index += 1
                continue
            if index < len(tokens) and tokens[index].text == "]":
                return Aggregate(tuple(items), token.start, tokens[index].end), index + 1
            here = tokens[min(index, len(tokens) - 1)]
            raise _error(here, f"{here.text!r} in an aggregate", "',' or ']'", source)
    if token.text in "+-" and index + 1 < len(tokens) and tokens[index + 1].kind == "number":
        number = tokens[index + 1]
        sign = -1.0 if token.text == "-" else 1.0
        return Number(sign * float(number.text), token.start, number.end), index + 2
    if token.kind == "number":
        return Number(float(token.text), token.start, token.end), index + 1
    if token.kind in ("name", "string"):
        return Word(token.text, token.start, token.end), index + 1
    raise _error(token, f"{token.text!r}", "a literal: a number, TRUE/FALSE, a string or "
                 "'[...]'", source)


def _statement_end(tokens: Sequence[Token], index: int) -> int:
    """The index of the ``;`` that ends the statement at ``index`` (brackets skipped)."""
    depth = 0
    while index < len(tokens):
        text = tokens[index].text
        if text in "[({":
            depth += 1
        elif text in "])}":
            depth -= 1
        elif text == ";" and depth <= 0:
            return index
        index += 1
    return index


def _declaration(tokens: Sequence[Token], index: int, routine: str | None, source: str
                 ) -> tuple[Declaration | None, int]:
    """A declaration whose storage keyword is at ``index`` (after LOCAL/TASK)."""
    end = _statement_end(tokens, index)
    parts = tokens[index:end]
    if len(parts) < 3 or parts[1].kind != "name" or parts[2].kind != "name":
        return None, end + 1
    storage, kind, name = parts[0].text.upper(), parts[1].text.lower(), parts[2].text
    rest = 3
    array = rest < len(parts) and parts[rest].text == "{"
    if array:
        while rest < len(parts) and parts[rest].text != "}":
            rest += 1
        rest += 1
    value: Value | None = None
    if rest + 1 < len(parts) and parts[rest].text == ":=" and parts[rest + 1].text == "[":
        literal, after = parse_literal(tokens, index + rest + 1, source)
        value = literal if index + rest + 1 < after and after == end else None
    return Declaration(storage, kind, name, routine, value, array, parts[0].line), end + 1


def _split(tokens: Sequence[Token]) -> list[list[Token]]:
    """Arguments at bracket depth 0, split at commas."""
    parts: list[list[Token]] = [[]]
    depth = 0
    for token in tokens:
        if token.text in "[({":
            depth += 1
        elif token.text in "])}":
            depth -= 1
        if token.text == "," and depth == 0:
            parts.append([])
        else:
            parts[-1].append(token)
    return parts


def _move(tokens: Sequence[Token], index: int, routine: str | None) -> tuple[MoveInstruction, int]:
    """The motion instruction whose name is at ``index``."""
    end = _statement_end(tokens, index)
    roles = MOVES[tokens[index].text.lower()]
    positional: list[Argument] = []
    wobj = None
    for part in _split(tokens[index + 1:end]):
        depth, cut = 0, len(part)
        for k, token in enumerate(part):
            depth += token.text in "[({"
            depth -= token.text in "])}"
            if token.text == "\\" and depth == 0:
                cut = k
                break
        optional = part[cut:]
        for k, token in enumerate(optional):
            if token.text == "\\" and k + 1 < len(optional) \
                    and optional[k + 1].text.lower() == "wobj":
                value = optional[k + 3:]
                stop = next((j for j, t in enumerate(value) if t.text == "\\"), len(value))
                wobj = "".join(t.text for t in value[:stop])
        if part[:cut] and len(positional) < len(roles):
            positional.append(Argument(roles[len(positional)], tuple(part[:cut])))
    move = MoveInstruction(tokens[index].text, tokens[index].line, routine, tuple(positional), wobj)
    return move, end + 1


def parse_module(text: str, source: str | Path) -> Module:
    """The declarations and motion instructions of a module's text.

    Raises:
        InputError: for text that is not RAPID or a target literal that does not parse
            (naming the line).
    """
    where = str(source)
    tokens = tokenize(text, where)
    declarations: list[Declaration] = []
    moves: list[MoveInstruction] = []
    routine: str | None = None
    index = 0
    while index < len(tokens):
        token = tokens[index]
        word = token.text.lower() if token.kind == "name" else ""
        following = tokens[index + 1].text if index + 1 < len(tokens) else ""
        if word in ROUTINE_STARTS:
            names = [t for t in tokens[index + 1:index + 3] if t.kind == "name"]
            routine = names[-1 if word == "func" else 0].text.lower() if names else word
            index += 1
        elif word in ROUTINE_ENDS:
            routine = None
            index += 1
        elif word in ("local", "task") and following.lower() in STORAGE:
            index += 1
        elif word in STORAGE:
            declaration, index = _declaration(tokens, index, routine, where)
            if declaration is not None:
                declarations.append(declaration)
        elif word in MOVES and following not in (":=", "("):
            move, index = _move(tokens, index, routine)
            moves.append(move)
        else:
            index += 1
    return Module(text, tuple(declarations), tuple(moves), tuple(tokens), where)


def read_module(path: str | Path) -> Module:
    """Read and parse a RAPID module file (:func:`parse_module`)."""
    raw = read_bytes(path, WHAT)
    if b"\x00" in raw:
        raise InputError("binary data", WHAT, source=path)
    return parse_module(raw.decode(ENCODING), path)


class RobTarget(NamedTuple):
    """A robtarget literal: ``trans`` (3), ``rot`` (4, scalar first), ``robconf`` (4),
    ``extax`` (6), each number with its place."""

    trans: tuple[Number, ...]
    rot: tuple[Number, ...]
    robconf: tuple[Number, ...]
    extax: tuple[Number, ...]

    @property
    def trans_mm(self) -> Array:
        """Shape (3,), mm."""
        return np.array([n.value for n in self.trans])

    @property
    def quaternion(self) -> Array:
        """Shape (4,), scalar first."""
        return np.array([n.value for n in self.rot])

    @property
    def configuration(self) -> Array:
        """cf1, cf4, cf6, cfx, shape (4,)."""
        return np.array([n.value for n in self.robconf])


class JointTarget(NamedTuple):
    """A jointtarget literal: ``robax`` (6, degrees) and ``extax`` (6), with their places."""

    robax: tuple[Number, ...]
    extax: tuple[Number, ...]

    @property
    def robax_deg(self) -> Array:
        """Shape (6,), degrees."""
        return np.array([n.value for n in self.robax])


class Frame(NamedTuple):
    """A ``pose`` literal ``[[x, y, z], [q1, q2, q3, q4]]``: mm and a quaternion."""

    trans_mm: Array
    quaternion: Array


class ToolData(NamedTuple):
    """A tooldata literal: whether the robot holds the tool, and its TCP in tool0."""

    robhold: bool
    tframe: Frame


class WobjData(NamedTuple):
    """A wobjdata literal: whether the robot holds it, whether its user frame is fixed
    (``ufprog``), the mechanical unit moving it (``ufmec``, empty for none), its frames."""

    robhold: bool
    ufprog: bool
    ufmec: str
    uframe: Frame
    oframe: Frame


def _numbers(value: Value, count: int, what: str) -> tuple[Number, ...]:
    if not isinstance(value, Aggregate) or len(value.items) != count \
            or not all(isinstance(item, Number) for item in value.items):
        raise ValueError(f"{what}: expected {count} numbers")
    return tuple(item for item in value.items if isinstance(item, Number))


def _parts(value: Value, count: int, what: str) -> tuple[Value, ...]:
    if not isinstance(value, Aggregate) or len(value.items) != count:
        raise ValueError(f"{what}: expected [{', '.join(['…'] * count)}]")
    return value.items


def _flag(value: Value, what: str) -> bool:
    if not isinstance(value, Word) or value.text.upper() not in ("TRUE", "FALSE"):
        raise ValueError(f"{what}: expected TRUE or FALSE")
    return value.text.upper() == "TRUE"


def _frame(value: Value, what: str) -> Frame:
    trans, rot = _parts(value, 2, what)
    return Frame(np.array([n.value for n in _numbers(trans, 3, f"{what}.trans")]),
                 np.array([n.value for n in _numbers(rot, 4, f"{what}.rot")]))


def robtarget(value: Value) -> RobTarget:
    """The robtarget of a literal.

    Raises:
        ValueError: naming the component that does not have the robtarget's shape.
    """
    trans, rot, robconf, extax = _parts(value, 4, "robtarget")
    return RobTarget(_numbers(trans, 3, "trans"), _numbers(rot, 4, "rot"),
                     _numbers(robconf, 4, "robconf"), _numbers(extax, 6, "extax"))


def jointtarget(value: Value) -> JointTarget:
    """The jointtarget of a literal.

    Raises:
        ValueError: naming the component that does not have the jointtarget's shape.
    """
    robax, extax = _parts(value, 2, "jointtarget")
    return JointTarget(_numbers(robax, 6, "robax"), _numbers(extax, 6, "extax"))


def tooldata(value: Value) -> ToolData:
    """The tooldata of a literal (its load is not read: compensation does not use it).

    Raises:
        ValueError: naming the component that does not have the tooldata's shape.
    """
    robhold, tframe, _ = _parts(value, 3, "tooldata")
    return ToolData(_flag(robhold, "robhold"), _frame(tframe, "tframe"))


def wobjdata(value: Value) -> WobjData:
    """The wobjdata of a literal.

    Raises:
        ValueError: naming the component that does not have the wobjdata's shape.
    """
    robhold, ufprog, ufmec, uframe, oframe = _parts(value, 5, "wobjdata")
    if not isinstance(ufmec, Word):
        raise ValueError("ufmec: expected a string")
    return WobjData(_flag(robhold, "robhold"), _flag(ufprog, "ufprog"), ufmec.text.strip('"'),
                    _frame(uframe, "uframe"), _frame(oframe, "oframe"))


def format_number(value: float, decimals: int) -> str:
    """A number as RAPID reads it, rounded to ``decimals`` places, trailing zeros dropped
    (``-0`` written ``0``)."""
    text = f"{round(float(value), decimals) + 0.0:.{decimals}f}"
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def rewrite(text: str, changes: Sequence[tuple[Number, str]]) -> str:
    """The text with each number's characters replaced by its new text, every other character
    as it was.

    Raises:
        ValueError: if two changes overlap.
    """
    ordered = sorted(changes, key=lambda change: change[0].start)
    pieces: list[str] = []
    position = 0
    for number, new in ordered:
        if number.start < position:
            raise ValueError("overlapping changes")
        pieces += [text[position:number.start], new]
        position = number.end
    pieces.append(text[position:])
    return "".join(pieces)
