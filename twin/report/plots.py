"""Matplotlib, set up once for every figure `twin` draws, and the figures of the commands.

Figures are drawn on the Agg backend (no display, no window, the same pixels on a server as on
a desktop); the caller writes them (:func:`twin.io.png.save_png`, one resolution, atomically).
Matplotlib is imported on first use: commands that draw nothing do not pay for it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from twin.arrays import Array
from twin.report.display import mm
from twin.units import m_to_mm

if TYPE_CHECKING:
    from twin.compensation.check import CompensationCheck

def pyplot() -> Any:
    """``matplotlib.pyplot`` on the Agg backend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def compensation_histogram(checks: dict[str, CompensationCheck], title: str) -> Any:
    """The figure of the histograms of the true flange error without and with each
    compensation (log x).

    Args:
        checks: Per compensation, the true flange errors (the first one's nominal errors
            are drawn as "nominal joints").
        title: The figure's title.
    """
    plt = pyplot()
    first = next(iter(checks.values()))
    series = [("nominal joints", first.nominal_error_m)] + [
        (f"compensated, {label}", check.compensated_error_m) for label, check in checks.items()
    ]
    errors_mm = np.concatenate([m_to_mm(values) for _, values in series])
    low = max(float(errors_mm.min()), 1e-6)
    bins = np.geomspace(low, float(errors_mm.max()), 60).tolist()
    figure, axes = plt.subplots(figsize=(6.4, 4.0), layout="constrained")
    for label, values in series:
        rms = mm(np.sqrt(np.mean(values**2)))
        axes.hist(np.maximum(m_to_mm(values), low), bins=bins, alpha=0.6,
                  label=f"{label} (RMS {rms})")
    axes.set_xscale("log")
    axes.set_xlabel("true flange position error [mm]")
    axes.set_ylabel("targets")
    axes.legend(fontsize=8)
    axes.set_title(title, fontsize=9)
    return figure


def accuracy_map(q2_rad: Array, q3_rad: Array, error_m: Array, title: str) -> Any:
    """The figure of the predicted flange error over a (q2, q3) grid.

    Args:
        q2_rad: The grid's q2, shape (a,), rad.
        q3_rad: The grid's q3, shape (b,), rad.
        error_m: Predicted flange position error, RMS, shape (a, b), m.
        title: The figure's title.
    """
    plt = pyplot()
    figure, axes = plt.subplots(figsize=(6.4, 4.8), layout="constrained")
    image = axes.pcolormesh(np.rad2deg(q3_rad), np.rad2deg(q2_rad), m_to_mm(error_m),
                            shading="auto", cmap="viridis")
    figure.colorbar(image, ax=axes, label="predicted flange position error, RMS [mm]")
    axes.set_xlabel("q3 [deg]")
    axes.set_ylabel("q2 [deg]")
    axes.set_title(title, fontsize=9)
    return figure
