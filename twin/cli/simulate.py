"""`twin simulate`: synthetic cable data with known truth from the MuJoCo twin."""

from __future__ import annotations

import argparse
import warnings

from twin.cli.arguments import (
    add_output,
    add_scenario,
    add_seed,
)
from twin.errors import InputError
from twin.io.paths import CAPTURE_FOLDER
from twin.viz.options import add_rerun_flags

NAME = "simulate"
HELP = "simulate a capture with the MuJoCo digital twin"
DESCRIPTION = (
    "Simulate a drawstring-encoder capture of a perturbed robot as described by "
    "a scenario TOML, and write measurements.csv, robot.toml (nominal model), truth.json "
    "and capture.toml to --out; `twin calibrate OUT/capture.toml` then needs nothing else. "
    "A folder that holds real measurements (a `twin capture`) is refused unless --force."
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The subcommand's arguments."""
    add_scenario(parser)
    add_output(parser, "DIR", "output folder", folder=CAPTURE_FOLDER)
    add_seed(parser, "seed of every random draw (default: the scenario's)")
    parser.add_argument("--force", action="store_true",
                        help="write into a folder that holds real measurements (a capture): "
                        "its files are first moved into DIR/kept-<UTC time>/, never deleted")
    add_rerun_flags(parser)


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    import numpy as np

    from twin.hardware.capture_session import real_measurements, set_aside
    from twin.io.lock import folder_lock
    from twin.kinds import KINDS
    from twin.report.display import LENGTH_DECIMALS, plain, xyz_mm
    from twin.scenario import load_scenario
    from twin.sim import simulate, write_simulation
    from twin.viz.commands import record_simulation

    with folder_lock(args.out, "twin simulate"):
        real = real_measurements(args.out)
        if real is not None and not args.force:
            raise InputError(real[1], "a folder without real measurements: a new --out "
                             "folder, or --force to move them into DIR/kept-<UTC time>/ "
                             "first", source=real[0])
        scenario = load_scenario(args.scenario)
        sim = simulate(scenario, seed=args.seed)
        if real is not None:
            kept, moved = set_aside(args.out)
            warnings.warn(f"{args.out} held {real[1]}: {', '.join(moved)} moved to {kept} "
                          "(--force), nothing deleted", stacklevel=1)
        capture = write_simulation(args.out, sim)
    effects = sim.effects  # in mm, as truth.json keeps them
    print(f"{scenario.name}: {len(sim.measurements)} poses, seed {sim.seed}, "
          f"{'compliant' if not scenario.physics.rigid else 'rigid'} joints")
    shown = {key: f"{plain(value, LENGTH_DECIMALS)} mm" for key, value in effects.items()}
    print(f"  nominal model vs readings: RMSE {shown['nominal_rmse_mm']}")
    kind = KINDS.lookup(sim.measurements.kind)
    print(f"  non-geometric share of the {kind.reading_noun}: RMS {shown['non_geometric_mm']}; "
          f"flange shift by joint errors and sag: RMS {shown['flange_shift_mm']}")
    if sim.outlier_rows.size:
        print(f"  {sim.outlier_rows.size} outliers")
    told = sim.rig_told
    for name, port_m in zip(told.port_names, told.ports_m, strict=True):
        print(f"  port {'' if len(told.ports_m) == 1 else name + ' '}told to the calibration: "
              f"{xyz_mm(port_m)}")
    if not kind.on_flange or np.any(np.abs(sim.rig.attachment_m) > 0):
        print(f"  measured point in the flange frame: {xyz_mm(sim.rig.attachment_m)}, "
              f"told {xyz_mm(told.attachment_m)}")
    if sim.rig.point_names:
        print(f"  {len(sim.rig.point_names)} fixed points, {len(told.distances)} known "
              "distances told")
    print(f"wrote {capture} (calibrate with: twin calibrate {capture})")
    record_simulation(args, sim)
    return 0
