"""Rerun visualisation of simulations, calibrations and studies (an adapter).

Importing this package does not import ``rerun``: the CLI adds the ``--rerun-*`` flags with
:func:`add_rerun_flags` and opens a recording with :func:`open_from_args`, which imports the
recording modules (and ``rerun``) only when a flag asks for them. See ``docs/rerun.md``.

- :mod:`~twin.viz.options`: where a recording goes (:class:`RerunOptions`, the flags); no rerun;
- :mod:`~twin.viz.commands`: what the commands call (:func:`open_from_args`…); no rerun;
- :mod:`~twin.viz.recording`: the recording façade commands log through;
- :mod:`~twin.viz.sinks`: the ``.rrd`` file and the viewer processes (spawn, serve);
- :mod:`~twin.viz.scene`, :mod:`~twin.viz.calibration_log`, :mod:`~twin.viz.recording_report`,
  :mod:`~twin.viz.blueprint`, :mod:`~twin.viz.entities`, :mod:`~twin.viz.writer`: what is
  logged, where, and how it is laid out.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from twin.distribution import lazy_exports

if TYPE_CHECKING:
    from twin.viz.commands import calibration_log, open_from_args, record_simulation
    from twin.viz.options import RerunOptions, add_rerun_flags, rerun_options

__getattr__ = lazy_exports(__name__, {
    "twin.viz.commands": ("calibration_log", "open_from_args", "record_simulation"),
    "twin.viz.options": ("RerunOptions", "add_rerun_flags", "rerun_options")})

__all__ = [
    "RerunOptions",
    "add_rerun_flags",
    "calibration_log",
    "open_from_args",
    "record_simulation",
    "rerun_options",
]
