"""Where a Rerun recording goes: the :class:`RerunOptions` value and the ``--rerun-*`` flags
shared by `twin simulate`, `twin calibrate` and `twin study`.

This module imports nothing heavy (no ``rerun``): the CLI builds its parser with it, and the
recording modules (:mod:`twin.viz.recording`, :mod:`twin.viz.sinks`) take the value from here.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

from twin.io.paths import OutputFile

DEFAULT_WEB_PORT = 9090
DEFAULT_GRPC_PORT = 9876


@dataclass(frozen=True)
class RerunOptions:
    """Where a recording goes.

    Attributes:
        save: ``.rrd`` file to write, or None.
        spawn: Start the native viewer and stream to it.
        serve: Serve the web viewer and a gRPC server on 127.0.0.1 until Ctrl-C.
        web_port: Port of the web viewer (HTTP) when serving.
        grpc_port: Port of the gRPC server the web viewer reads from; also the native
            viewer's port when spawning.
    """

    save: Path | None = None
    spawn: bool = False
    serve: bool = False
    web_port: int = DEFAULT_WEB_PORT
    grpc_port: int = DEFAULT_GRPC_PORT

    def __post_init__(self) -> None:
        for name in ("web_port", "grpc_port"):
            port = getattr(self, name)
            if not 0 < port < 65536:
                raise ValueError(f"{name}: {port}, expected 1..65535")

    @property
    def enabled(self) -> bool:
        """Whether anything is to be recorded."""
        return self.save is not None or self.spawn or self.serve


def _port(text: str) -> int:
    """A TCP port number, for argparse (which reports a bad one and exits with code 2)."""
    try:
        port = int(text)
    except ValueError:
        port = 0
    if not 0 < port < 65536:
        raise argparse.ArgumentTypeError(f"found {text!r}, expected a TCP port in 1..65535")
    return port


def add_rerun_flags(parser: argparse.ArgumentParser) -> None:
    """Add ``--rerun-save``, ``--rerun-spawn``, ``--rerun-serve`` and their port options."""
    group = parser.add_argument_group("Rerun visualisation (see docs/rerun.md)")
    group.add_argument("--rerun-save", type=OutputFile, metavar="FILE.rrd",
                       help="write a Rerun recording; open it later with `rerun FILE.rrd`")
    group.add_argument("--rerun-spawn", action="store_true",
                       help="stream to the native Rerun viewer (needs a display; without one "
                       "the recording is saved to a file instead)")
    group.add_argument("--rerun-serve", action="store_true",
                       help="serve the web viewer on 127.0.0.1 (headless machines): prints the "
                       "URL and keeps serving until Ctrl-C")
    group.add_argument("--rerun-web-port", type=_port, default=DEFAULT_WEB_PORT, metavar="PORT",
                       help=f"web viewer port for --rerun-serve (default {DEFAULT_WEB_PORT})")
    group.add_argument("--rerun-grpc-port", type=_port, default=DEFAULT_GRPC_PORT, metavar="PORT",
                       help="gRPC port of the served or spawned viewer "
                       f"(default {DEFAULT_GRPC_PORT})")


def rerun_options(args: argparse.Namespace) -> RerunOptions:
    """The options the flags of :func:`add_rerun_flags` parsed to."""
    return RerunOptions(save=args.rerun_save, spawn=args.rerun_spawn, serve=args.rerun_serve,
                        web_port=args.rerun_web_port, grpc_port=args.rerun_grpc_port)
