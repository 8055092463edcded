"""The `twin` command line. Each subcommand is a module named after it, ``twin/cli/<command>.py``
(``virtual-encoder``: ``virtual_encoder.py``), which states its ``NAME``, ``HELP`` and
``DESCRIPTION``, its arguments (``add_arguments(parser)``) and ``run(args)``: it parses, calls
the library and prints. Where the library function a command calls has the
command's name, its module may too (`twin simulate` calls :func:`twin.sim.simulate.simulate`,
`twin predict` :func:`twin.calibration.predict.predict`, `twin check`
:func:`twin.study.check.check`, `twin virtual-encoder` :mod:`twin.hardware.virtual_encoder`): a
module of ``twin/cli/`` is the command, the other the thing it runs. What several commands parse
alike is in :mod:`twin.cli.arguments` (flag types and shared flag sets) and :mod:`twin.cli.inputs`
(what a calibration's INPUT and rig flags resolve to).

User mistakes (:class:`~twin.errors.InputError`, a bad flag, an ``OSError`` on a named file,
an adapter library whose extra is not installed) print one line on stderr and exit with code 2;
no traceback. Faults that are not the user's
(a device that stops answering mid-capture) exit with code 1, a crash with a traceback.

Before a command runs, every output path it names is checked against the rules of
:mod:`twin.io.paths` (never one of its inputs, never a directory, device or FIFO, a writable
folder, never where another of its outputs goes), and no output file may replace a capture's
measurements, so that a mistake costs no work and overwrites nothing.

SIGTERM stops a command as Ctrl-C does (a capture says which poses are saved), with exit code
143.
"""

from __future__ import annotations

import contextlib
import gc
import os
import signal
import sys
import threading
import warnings
from collections.abc import Iterator, Sequence
from types import FrameType
from typing import NoReturn

from twin import distribution
from twin.cli import (
    calibrate,
    capture,
    check,
    compensate,
    export,
    identify,
    import_,
    plan,
    predict,
    simulate,
    study,
    virtual_controller,
    virtual_encoder,
)
from twin.cli.arguments import ArgumentParser, UsageError
from twin.distribution import missing_extra
from twin.errors import InputError, TwinError
from twin.io.paths import check_command_paths, check_distinct_outputs, command_scope

SUBCOMMANDS = (calibrate, simulate, identify, plan, predict, compensate, export, study, check,
               capture, virtual_encoder, virtual_controller, import_)
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130
EXIT_BROKEN_PIPE = 141
EXIT_TERMINATED = 143


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the command is, so that it stops as on Ctrl-C: temporary files
    removed, a capture's saved poses reported, the folder's lock released."""


def _raise_terminated(signum: int, frame: FrameType | None) -> None:
    raise Terminated


@contextlib.contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """Turn SIGTERM into :class:`Terminated` for the block (in the main thread only, where
    Python runs signal handlers), then restore the previous handler."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def build_parser(argv: Sequence[str] | None = None) -> ArgumentParser:
    """The argument parser with every subcommand; for a command line ``argv``, only what
    parsing it reads: the command its first word names, alone, with its flags; without one
    (``--version``, ``--help``, a word that names no command), every command's name and help
    but none of their flags (building them all was 12 ms of every command's start)."""
    parser = ArgumentParser(
        prog="twin",
        description="Kinematic calibration of serial robots with a drawstring encoder, "
        "and its digital twin.",
    )
    parser.add_argument("--version", action="version",
                        version=f"{distribution.NAME} {distribution.version()}")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    # The top level has no flag that takes a value: its first other word is the command.
    named = next((word for word in argv or () if not word.startswith("-")), None)
    chosen = tuple(module for module in SUBCOMMANDS if named == module.NAME)
    for module in chosen or SUBCOMMANDS:
        command = subparsers.add_parser(module.NAME, help=module.HELP,
                                        description=module.DESCRIPTION)
        if chosen or argv is None:
            module.add_arguments(command)
        command.set_defaults(func=module.run)
    return parser


def _show_warning(
    message: Warning | str, category: type[Warning], filename: str, lineno: int,
    file: object = None, line: str | None = None,
) -> None:
    print(f"twin: warning: {message}", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the exit code."""
    try:
        args = build_parser(sys.argv[1:] if argv is None else argv).parse_args(argv)
    except UsageError as exc:
        print(f"twin: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    warnings.showwarning = _show_warning
    try:
        from twin.hardware.capture_layout import refuse_capture_journal

        with _sigterm_as_interrupt(), command_scope():
            distribution.kernel_choice()
            check_command_paths(vars(args).values())
            check_distinct_outputs(vars(args))
            refuse_capture_journal(vars(args).values())
            return int(args.func(args) or 0)
    except InputError as exc:
        print(f"twin: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except ImportError as exc:
        # The one place where an adapter's library that is not installed becomes the extra
        # to install: adapters import their libraries lazily and let the error rise.
        missing = missing_extra(exc, source=args.command)
        if missing is None:
            raise
        print(f"twin: error: {missing}", file=sys.stderr)
        return EXIT_USAGE
    except BrokenPipeError:
        # The reader of stdout went away (`| head`): stop quietly, as a killed pipe writer.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_BROKEN_PIPE
    except OSError as exc:
        if exc.filename is None:
            raise
        # Reading and writing convert their errors where they happen; this is the net below.
        print(f"twin: error: {exc.filename}: found {(exc.strerror or str(exc)).lower()}, "
              "expected a file that can be read or written", file=sys.stderr)
        return EXIT_USAGE
    except TwinError as exc:
        print(f"twin: error: {exc}", file=sys.stderr)
        return 1
    except Terminated:
        print("twin: terminated", file=sys.stderr)
        return EXIT_TERMINATED
    except KeyboardInterrupt:
        print("twin: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


def run() -> NoReturn:
    """The `twin` program (the console script, ``python -m twin``): :func:`main`, then exit
    with its code without the interpreter's last garbage collection.

    That collection walks every object the command left: in a process that had loaded the
    compiled kernels (numba's and llvmlite's objects), exiting took 0.28 s with it and 0.04 s
    without; after a calibration 0.07 s. By then every output is written, flushed and closed
    (atomic writes, durable journals), and the atexit handlers (Rerun's flush, temporary
    folders) still run; what is left uncollected is memory the process gives back as it ends.
    :func:`main` itself leaves the collector alone: a program that calls it goes on."""
    code = main()
    gc.freeze()
    sys.exit(code)
