"""The rules every file `twin` reads or writes goes through, in one place.

Reading (:func:`read_bytes`, and :func:`read_text`, :func:`read_toml`, :func:`read_json` on top):

- only a regular file is opened (a FIFO without a writer would block forever, ``/dev/zero``
  never ends, a serial device resets on open), or ``-`` for standard input where a command
  allows it;
- at most :data:`MAX_FILE_BYTES`; TOML and JSON nested at most :data:`MAX_NESTING` deep (the
  parsers recurse; a file of ten thousand ``[`` must not crash them); CSV lines are limited by
  :func:`twin.io.measurements.read_table` to :data:`MAX_LINE_CHARS`;
- every ``OSError`` becomes one :class:`~twin.errors.InputError` naming the file and the
  operation.

Writing (:func:`check_output`, which the atomic writer and the CLI call):

- an output is never one of the command's inputs: the same device and inode, under whatever
  name (a hard link, a symbolic link);
- never an existing directory, device, FIFO or socket (as root, ``--json /dev/full`` would
  otherwise replace the device node with a regular file);
- its folder exists, or can be created, and is writable.

The CLI runs each command inside :func:`command_scope`: the inputs it names on the command line
are checked against its outputs before any work starts, and every file it reads on the way
(the measurements a ``capture.toml`` names, say) is remembered, so that the atomic writer
refuses to replace it.
"""

from __future__ import annotations

import contextlib
import fnmatch
import json
import os
import re
import stat
import sys
import tomllib
from collections.abc import Iterable, Iterator, Mapping
from contextvars import ContextVar
from itertools import accumulate
from pathlib import Path, PosixPath
from typing import Any

from twin.errors import InputError

MAX_FILE_BYTES = 256 * 2**20
"""Largest input file read, bytes (a measurement CSV of about two million poses)."""
MAX_LINE_CHARS = 65536
"""Longest line of a CSV file, characters (a pose takes about 150)."""
MAX_NESTING = 64
"""Deepest nesting of arrays and tables in a TOML or JSON input (ours go 6 deep)."""
STDIN = "-"
"""The path that stands for standard input, where a command allows it."""

_Identity = tuple[int, int]
_inputs: ContextVar[set[_Identity] | None] = ContextVar("twin_inputs", default=None)


class InputPath(PosixPath):
    """A command-line path the command reads (an argparse ``type``)."""


class OutputFile(PosixPath):
    """A command-line path the command writes a file to (an argparse ``type``)."""


class OutputFolder(PosixPath):
    """A command-line path of a folder the command writes files into (an argparse ``type``;
    :func:`output_folder` makes one that names the files)."""

    writes: tuple[str, ...] = ()
    """Patterns (``fnmatch``, of a name directly in the folder) of what the command writes
    there; empty when not stated: then no other output of the command may lie inside it."""


def output_folder(*writes: str) -> type[OutputFolder]:
    """The argparse ``type`` of a folder into which the command writes files named as
    ``writes`` (patterns such as ``results.csv``, ``*.png``, ``kept-*``), so that another output
    of the command may go into the folder under any other name (``--rerun-save DIR/run.rrd``)
    but never replace one of them (``--junit DIR/results.csv``)."""
    return type("OutputFolder", (OutputFolder,), {"writes": tuple(writes)})


STUDY_FOLDER = ("results.csv", "trials.jsonl", "study.json", "summary.json", "summary.md",
                "*.png", ".lock*")
"""What `twin study` and `twin check` write into their folder (:mod:`twin.study.store`,
:mod:`twin.study.runner`, :mod:`twin.study.figures`, :mod:`twin.io.lock`)."""
CAPTURE_FOLDER = ("measurements.csv", "plan.csv", "capture.toml", "robot.*", "truth.json",
                  "*.mod", "kept-*", ".lock*")
"""What `twin simulate` and `twin capture` write into their folder (the capture's files,
:mod:`twin.hardware.capture_session`; the robot program of a plan; the folder a real capture
is moved into; the lock)."""


def _kind(mode: int) -> str:
    """What a non-regular file is, for messages."""
    for test, name in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "not a regular file"


def os_error(path: str | Path, operation: str, exc: OSError, expected: str) -> InputError:
    """The one-line error of an ``OSError`` met while ``operation`` (reading, writing…)."""
    reason = (exc.strerror or exc.__class__.__name__).lower()
    return InputError(f"{reason} while {operation}", expected, source=path)


@contextlib.contextmanager
def command_scope() -> Iterator[None]:
    """Remember the inputs read inside the block, so that no output replaces one of them."""
    token = _inputs.set(set())
    try:
        yield
    finally:
        _inputs.reset(token)


def protect(path: str | Path) -> None:
    """Count ``path`` as an input of the running command (if it exists and a command runs)."""
    inputs = _inputs.get()
    if inputs is None or str(path) == STDIN:
        return
    with contextlib.suppress(OSError):
        info = os.stat(path)
        inputs.add((info.st_dev, info.st_ino))


def read_bytes(path: str | Path, what: str, *, stdin: bool = False,
               journal: bool = False) -> bytes:
    """The bytes of an input file: a regular file of at most :data:`MAX_FILE_BYTES`.

    Args:
        path: The file, or ``-`` for standard input if ``stdin``.
        what: What the file should be, for messages ("a measurement CSV…").
        stdin: Whether ``-`` means standard input.
        journal: The command's own resumable file (a capture's measurements, a study's
            results), which it may rewrite: not protected as an input and not size-limited.

    Raises:
        InputError: if it is missing, not a regular file, too large or unreadable.
    """
    limit = None if journal else MAX_FILE_BYTES
    if stdin and str(path) == STDIN:
        return _limited(sys.stdin.buffer.read(limit + 1 if limit else -1), limit, "-", what)
    path = Path(path)
    try:
        # stat before open: opening a serial device may reset what hangs on it.
        mode = os.stat(path).st_mode
        if not stat.S_ISREG(mode):
            raise InputError(_kind(mode), what, source=path)
        # O_NONBLOCK: should a FIFO have replaced the file since, open must not wait for it.
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except FileNotFoundError:
        raise InputError("no such file", what, source=path) from None
    except NotADirectoryError:
        raise InputError("a path under a regular file", what, source=path) from None
    except OSError as exc:
        raise os_error(path, "opening it", exc, what) from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise InputError(_kind(info.st_mode), what, source=path)
        if limit is not None and info.st_size > limit:
            raise InputError(f"{info.st_size} bytes", f"{what} of at most {limit} bytes",
                             source=path)
        os.set_blocking(fd, True)
        with os.fdopen(fd, "rb", closefd=False) as handle:
            raw = handle.read(limit + 1 if limit else -1)
    except OSError as exc:
        raise os_error(path, "reading it", exc, what) from None
    finally:
        os.close(fd)
    if not journal:
        protect(path)
    return _limited(raw, limit, path, what)


def _limited(raw: bytes, limit: int | None, path: str | Path, what: str) -> bytes:
    if limit is not None and len(raw) > limit:
        raise InputError(f"more than {limit} bytes", f"{what} of at most {limit} bytes",
                         source=path)
    return raw


def read_text(path: str | Path, what: str, *, stdin: bool = False,
              journal: bool = False) -> str:
    """The UTF-8 text of an input file (see :func:`read_bytes`); binary data is refused."""
    return decode_text(read_bytes(path, what, stdin=stdin, journal=journal), path, what)


def decode_text(raw: bytes, path: str | Path, what: str) -> str:
    """The UTF-8 text of a file's bytes (a BOM is dropped).

    Raises:
        InputError: for binary data (a NUL byte) or bytes that are not UTF-8.
    """
    if b"\x00" in raw:
        raise InputError("binary data", what, source=path)
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"bytes that are not UTF-8 at offset {exc.start}", what,
                         source=path) from None


# Strings and comments, whose brackets do not nest: TOML's four kinds of string (JSON's one is
# among them) and its comments.
_NOT_NESTING = re.compile(
    r'"""(?:\\.|[^\\])*?"""|\'\'\'.*?\'\'\'|"(?:\\.|[^"\\\n])*"|\'[^\'\n]*\'|#[^\n]*', re.S)


def check_nesting(text: str, path: str | Path, what: str) -> None:
    """Refuse brackets nested deeper than :data:`MAX_NESTING` before a parser recurses in."""
    brackets = re.findall(r"[\[\]{}]", _NOT_NESTING.sub("", text))
    depth = max(accumulate(1 if b in "[{" else -1 for b in brackets), default=0)
    if depth > MAX_NESTING:
        raise InputError(f"arrays or tables nested {depth} deep", f"{what} nested at most "
                         f"{MAX_NESTING} deep", source=path)


def _check_depth(document: Any, path: str | Path, what: str) -> None:
    """Refuse a parsed document nested too deep (TOML dotted keys nest without brackets)."""
    stack = [(document, 0)]
    while stack:
        node, depth = stack.pop()
        children = node.values() if isinstance(node, dict) else node \
            if isinstance(node, list) else ()  # a scalar document
        if depth >= MAX_NESTING and len(children):  # a child one deeper than allowed
            raise InputError(f"keys nested more than {MAX_NESTING} deep",
                             f"{what} nested at most {MAX_NESTING} deep", source=path)
        # Only containers are stacked: a list of a million numbers is walked once (0.58 s
        # stacked, 0.10 s walked, on a 6 MB scenario's sweep, side by side).
        stack.extend((child, depth + 1) for child in children
                     if isinstance(child, (dict, list)))


def read_toml(path: str | Path, what: str) -> dict[str, Any]:
    """The parsed document of a TOML input file.

    Raises:
        InputError: if the file cannot be read, is not TOML or is nested too deep.
    """
    text = read_text(path, what)
    check_nesting(text, path, what)
    try:
        document = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"invalid TOML ({exc})", what, source=path) from None
    _check_depth(document, path, what)
    return document


def read_json(path: str | Path, what: str, *, journal: bool = False) -> Any:
    """The parsed document of a JSON input file (``journal``: see :func:`read_bytes`).

    Raises:
        InputError: if the file cannot be read, is not JSON or is nested too deep.
    """
    text = read_text(path, what, journal=journal)
    check_nesting(text, path, what)
    try:
        document = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"invalid JSON ({exc.msg} at line {exc.lineno})", what,
                         source=path) from None
    except ValueError as exc:  # a number with more digits than Python converts
        raise InputError(f"invalid JSON ({exc})", what, source=path) from None
    return document


def check_output(path: str | Path, *, folder: bool = False) -> None:
    """Refuse an output path that would overwrite an input or cannot be written.

    Args:
        path: Where a file (or, with ``folder``, a folder of files) will be written.
        folder: The path is a folder the command writes into.

    Raises:
        InputError: if the path is an input of the running command, an existing directory
            (a file for ``folder``), device, FIFO or socket, lies under a regular file, or its
            folder is not writable.
    """
    path = Path(path)
    expected = "a folder to write into" if folder else "a regular file to create or replace"
    try:
        info: os.stat_result | None = os.stat(path)
    except FileNotFoundError:
        info = None
    except NotADirectoryError:
        info = None  # reported below, with the regular file it lies under
    except OSError as exc:
        raise os_error(path, "looking at it", exc, expected) from None
    if info is not None:
        if folder:
            if not stat.S_ISDIR(info.st_mode):
                raise InputError(_kind(info.st_mode) if not stat.S_ISREG(info.st_mode)
                                 else "a file", expected, source=path)
            _check_writable(path, path, expected)
            return
        if not stat.S_ISREG(info.st_mode):
            raise InputError(_kind(info.st_mode), expected, source=path)
        inputs = _inputs.get()
        if inputs is not None and (info.st_dev, info.st_ino) in inputs:
            raise InputError("one of this command's inputs", "an output that is not an input "
                             "(it would be overwritten)", source=path)
    parent = path.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    _check_writable(parent, path, expected)


def _check_writable(folder: Path, path: Path, expected: str) -> None:
    """The closest existing folder of ``path`` must be a folder we may create files in."""
    if not folder.is_dir():
        raise InputError(f"a path under the file {folder}", expected, source=path)
    if not os.access(folder, os.W_OK | os.X_OK):
        raise InputError(f"a folder {folder} that is not writable", expected, source=path)


def check_command_paths(values: Iterable[object]) -> None:
    """What the CLI calls before a command runs: protect its command-line inputs, then check
    its command-line outputs (:class:`InputPath`, :class:`OutputFile`, :class:`OutputFolder`
    values, or lists of them, among ``values``)."""
    flat: list[object] = []
    for value in values:
        flat.extend(value if isinstance(value, list) else [value])
    for value in flat:
        if isinstance(value, InputPath):
            protect(value)
    for value in flat:
        if isinstance(value, OutputFile | OutputFolder):
            check_output(value, folder=isinstance(value, OutputFolder))



def _same_place(first: Path, second: Path) -> bool:
    """Whether two paths name one file: the same resolved name, or the same device and inode
    (a hard link)."""
    if os.path.realpath(first) == os.path.realpath(second):
        return True
    try:
        one, two = os.stat(first), os.stat(second)
    except OSError:
        return False
    return (one.st_dev, one.st_ino) == (two.st_dev, two.st_ino)


def _check_inside(inner_flag: str, inner: Path, outer_flag: str, outer: Path) -> None:
    """Refuse the output ``inner`` under the output ``outer`` when it would replace one of
    outer's files: under a file output always; in a folder output when its name is one the
    folder's command writes (:attr:`OutputFolder.writes`; any name when it states none)."""
    place = os.path.realpath(outer) + os.sep
    if not os.path.realpath(inner).startswith(place):
        return
    if isinstance(outer, OutputFile):
        raise InputError(f"{inner}, a path under the {outer_flag} file",
                         "outputs apart from each other", source=inner_flag)
    if not isinstance(outer, OutputFolder):
        return
    name = os.path.realpath(inner)[len(place):].split(os.sep)[0]
    if not outer.writes:
        raise InputError(f"{inner}, a path inside the {outer_flag} folder",
                         "a path outside it (the command writes its own files there)",
                         source=inner_flag)
    if any(fnmatch.fnmatchcase(name, pattern) for pattern in outer.writes):
        raise InputError(f"{inner}, a file the command writes into the {outer_flag} folder",
                         "another name (the folder's own: " + ", ".join(outer.writes) + ")",
                         source=inner_flag)


def check_distinct_outputs(options: Mapping[str, object]) -> None:
    """Refuse two outputs of one command at the same place (``--junit DIR`` with ``--out
    DIR``, ``--json`` and ``--rerun-save`` one file), an output under a file output, or one
    that would replace a file the command writes into its folder (``--junit
    DIR/results.csv``), before any work.

    Args:
        options: The parsed arguments by destination (``vars(args)``); the
            :class:`OutputFile` and :class:`OutputFolder` values are the outputs.

    Raises:
        InputError: naming both flags.
    """
    outputs = [(f"--{dest.replace('_', '-')}", value) for dest, value in options.items()
               if isinstance(value, OutputFile | OutputFolder)]
    for index, (flag, path) in enumerate(outputs):
        for other, other_path in outputs[:index]:
            if _same_place(path, other_path):
                raise InputError(f"{path}, the same path as {other}", "an output of its own "
                                 "(one would replace the other)", source=flag)
            for inner_flag, inner, outer_flag, outer in ((flag, path, other, other_path),
                                                         (other, other_path, flag, path)):
                _check_inside(inner_flag, inner, outer_flag, outer)
