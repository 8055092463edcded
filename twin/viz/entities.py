"""Entity paths of a `twin` recording: the one place the layout is spelled out.

The roots (``world``, ``residuals``, ``convergence``, ``parameters``, ``report``) are a contract
with users and with the default blueprint; everything below them is built here. No ``rerun``
import: tests and the blueprint use the same names.
"""

from __future__ import annotations

from twin.units import DH_KEYS

BAR_KEYS = (*DH_KEYS[:2], "beta", *DH_KEYS[2:])
"""Rows of the parameter bar charts: the table's slots, with Hayati joints' β (degrees) apart
from D-H's d (mm), which share a slot."""

POSE_TIMELINE = "pose"
"""Sequence timeline over the measured poses (row index of the measurement file)."""
ITERATION_TIMELINE = "iteration"
"""Sequence timeline over solver iterations (0 is the start)."""

WORLD = "world"
PORT = "world/port"
CABLE = "world/cable"
MEASURED = "world/measured"
"""The measured points (tracker target, ball) of tracker and fixed-point data, base frame."""
FIXED_POINTS = "world/fixed_points"
RESIDUALS = "residuals"
RESIDUALS_BEFORE = "residuals/before"
CONVERGENCE = "convergence"
PARAMETERS = "parameters"
REPORT = "report"

CONVERGENCE_QUANTITIES = ("f", "train_rmse", "validation_rmse")
"""Series under ``convergence/<method>/``: f in mm², the two RMSEs in mm."""
EXACT = "exact"
"""Leaf under ``parameters/<source>/`` holding the exact values as float64 scalars, SI."""


def world(leaf: str) -> str:
    """What a measurement kind draws, e.g. ``world/port``, ``world/cable``, ``world/measured``."""
    return f"{WORLD}/{leaf}"


def robot(label: str) -> str:
    """Links of one robot, e.g. ``world/robot/nominal``, ``world/robot/identified/lm``."""
    return f"world/robot/{label}"


def identified_label(method: str) -> str:
    """Robot label of a method's identified model."""
    return f"identified/{method}"


def residuals_after(method: str) -> str:
    """Per-pose residuals after calibration by ``method``."""
    return f"residuals/after/{method}"


def residuals_rejected(method: str) -> str:
    """The poses a method's robust loss rejected, at their residual."""
    return f"residuals/rejected/{method}"


def convergence(method: str, quantity: str) -> str:
    """One convergence series of one method (``quantity`` in CONVERGENCE_QUANTITIES)."""
    return f"convergence/{method}/{quantity}"


def trial_convergence(method: str, trial: str) -> str:
    """One study trial's validation RMSE per iteration for one method (``trial`` names it)."""
    return f"convergence/{method}/trials/{trial}"


def parameter_source(method: str | None) -> str:
    """``parameters/identified/<method>``, or ``parameters/true`` for ``None``."""
    return f"parameters/identified/{method}" if method else "parameters/true"


def parameter_bars(method: str | None, key: str) -> str:
    """Bar chart of one table row (``key`` in :data:`BAR_KEYS`) of a source."""
    if key not in BAR_KEYS:
        raise ValueError(f"key {key!r}, expected one of {BAR_KEYS}")
    return f"{parameter_source(method)}/{key}"


def parameter_exact(method: str | None) -> str:
    """The exact float64 values of a source."""
    return f"{parameter_source(method)}/{EXACT}"
