"""Rerun visualisation of simulations, calibrations and studies (an adapter).

Importing this package does not import ``rerun``: the CLI adds the ``--rerun-*`` flags with
:func:`add_rerun_flags` and opens a recording with :func:`open_from_args`, which imports the
recording modules (and ``rerun``) only when a flag asks for them. See ``docs/rerun.md``.
"""

from twin.viz.cli import (
    RerunOptions,
    add_rerun_flags,
    calibration_log,
    open_from_args,
    record_simulation,
    rerun_options,
)

__all__ = [
    "RerunOptions",
    "add_rerun_flags",
    "calibration_log",
    "open_from_args",
    "record_simulation",
    "rerun_options",
]
