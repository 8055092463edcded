"""The `twin` command line. Each subcommand is a module with ``add_parser(subparsers)``.

User mistakes (:class:`~twin.errors.InputError`) print one line on stderr and exit with code 2;
no traceback.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from collections.abc import Sequence

from twin.cli import (
    calibrate,
    capture,
    check,
    compensate,
    export,
    identify,
    plan,
    simulate,
    study,
    virtual_encoder,
)
from twin.errors import InputError, TwinError

SUBCOMMANDS = (calibrate, simulate, identify, plan, compensate, export, study, check, capture,
               virtual_encoder)
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand."""
    parser = argparse.ArgumentParser(
        prog="twin",
        description="Kinematic calibration of serial robots with a drawstring encoder, "
        "and its digital twin.",
    )
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for module in SUBCOMMANDS:
        module.add_parser(subparsers)
    return parser


def _show_warning(
    message: Warning | str, category: type[Warning], filename: str, lineno: int,
    file: object = None, line: str | None = None,
) -> None:
    print(f"twin: warning: {message}", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the exit code."""
    args = build_parser().parse_args(argv)
    warnings.showwarning = _show_warning
    try:
        return int(args.func(args) or 0)
    except InputError as exc:
        print(f"twin: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except TwinError as exc:
        print(f"twin: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("twin: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
