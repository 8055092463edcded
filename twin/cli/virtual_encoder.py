"""`twin virtual-encoder`: a simulated drawstring encoder on a pseudo-terminal."""

from __future__ import annotations

import argparse
from pathlib import Path

from twin.cli.arguments import (
    add_scenario,
    add_seed,
    integer,
)
from twin.hardware.encoders import ENCODERS

URL_QUERY = {"ascii": "protocol=ascii", "modbus": "protocol=modbus&scale=0.001"}
"""What the driver needs besides the path: the Modbus device counts µm in registers 0–1."""


NAME = "virtual-encoder"
HELP = "serve a simulated encoder on a pseudo-terminal"
DESCRIPTION = (
    "Open a pseudo-terminal and answer on it as the real encoder would, with "
    "the twin's cable length at the pose the simulated robot was last sent to (see "
    "`twin capture --robot-source sim`). Prints the device path as its first line and a "
    "serial URL for `twin capture --encoder` as its second, then serves until stopped."
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The subcommand's arguments."""
    add_scenario(parser)
    parser.add_argument("--protocol", choices=tuple(ENCODERS), default="ascii",
                        help="ASCII line protocol or Modbus RTU (default: ascii)")
    add_seed(parser, "seed of the truth and of the noise (default: the scenario's)")
    parser.add_argument("--pose-file", type=Path, metavar="FILE",
                        help="where the simulated robot publishes its pose (default: a file in "
                        "the temporary folder, the same as twin capture's)")
    parser.add_argument("--slave", type=integer(1, 247), default=1,
                        help="Modbus slave id (default: 1)")
    parser.add_argument("--garbage-every", type=integer(0, 1_000_000), default=0, metavar="N",
                        help="corrupt every N-th answer, to test fault handling (default: never)")


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    from twin.hardware.robot_sources.sim import DEFAULT_POSE_FILE
    from twin.hardware.virtual_encoder import scenario_instrument, serve

    instrument = scenario_instrument(args.scenario, args.pose_file or DEFAULT_POSE_FILE,
                                     args.seed)

    def announce(path: str) -> None:
        print(path)
        print(f"serial://{path}?{URL_QUERY[args.protocol]}", flush=True)

    serve(instrument, args.protocol, slave_id=args.slave, garbage_every=args.garbage_every,
          announce=announce)
    return 0
