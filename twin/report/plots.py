"""Matplotlib, set up once for every figure `twin` draws, and the figures of the commands.

Figures are drawn on the Agg backend (no display, no window, the same pixels on a server as on
a desktop) and written as PNG at :data:`DPI`, atomically (:mod:`twin.io.atomic`), like every
other output. Matplotlib is imported on first use: commands that draw nothing do not pay for it.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from twin.arrays import Array
from twin.io.atomic import write_atomic
from twin.report.display import mm
from twin.units import m_to_mm

if TYPE_CHECKING:
    from twin.compensation.check import CompensationCheck

DPI = 120
"""Resolution of every PNG, dots per inch."""


def pyplot() -> Any:
    """``matplotlib.pyplot`` on the Agg backend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_png(figure: Any, path: str | Path, *, tight: bool = False) -> None:
    """Write ``figure`` to ``path`` as a PNG at :data:`DPI`, atomically, and close it.

    Args:
        figure: A matplotlib figure from :func:`pyplot`.
        path: The PNG file.
        tight: Crop the page to what is drawn (for figures laid out without
            ``layout="constrained"``).

    Raises:
        InputError: if ``path`` is not a valid output or cannot be written.
    """
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=DPI, bbox_inches="tight" if tight else None)
    pyplot().close(figure)
    write_atomic(path, buffer.getvalue())


def compensation_histogram(path: str | Path, checks: dict[str, CompensationCheck],
                           title: str) -> None:
    """PNG: histograms of the true flange error without and with each compensation (log x).

    Args:
        path: The PNG file.
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
    save_png(figure, path)


def accuracy_map(path: str | Path, q2_rad: Array, q3_rad: Array, error_m: Array,
                 title: str) -> None:
    """PNG: the predicted flange error over a (q2, q3) grid.

    Args:
        path: The PNG file.
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
    save_png(figure, path)
