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
    from twin.analysis.drift import Drift
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


def drift_figure(drift: Drift, title: str) -> Any:
    """The figure of each reference pose's readings against time (less their mean, mm), with
    their least-squares line and the band of ±1σ of the noise the test used, one panel per
    reference pose.

    Args:
        drift: The drift test (:mod:`twin.analysis.drift`), with at least one series.
        title: The figure's title.
    """
    plt = pyplot()
    count = len(drift.series)
    figure, panels = plt.subplots(count, 1, figsize=(6.4, 2.6 + 1.6 * count), squeeze=False,
                                  layout="constrained", sharex=True)
    noise_mm = float(m_to_mm(drift.noise_m))
    for k, (series, axes) in enumerate(zip(drift.series, panels[:, 0], strict=True)):
        centred = series.time_s - series.time_s.mean()
        axes.axhspan(-noise_mm, noise_mm, color="0.9", label=f"±σ {mm(drift.noise_m)}")
        for c in range(series.reading_m.shape[1]):
            label = f"row {c + 1}: z {series.z[c]:.3g}" if series.reading_m.shape[1] > 1 \
                else f"z {series.z[c]:.3g}"
            (line,) = axes.plot(series.time_s, m_to_mm(series.reading_m[:, c]), "o",
                                label=label)
            axes.plot(series.time_s, m_to_mm(centred * series.slope_m_per_s[c]), "-",
                      color=line.get_color())
        axes.set_ylabel(f"pose {k + 1}: reading\nless its mean [mm]", fontsize=8)
        axes.legend(fontsize=7, loc="best")
    panels[-1, 0].set_xlabel("time since the capture started [s]" if drift.timed
                             else "row of the capture")
    verdict = "drift beyond the noise" if drift.drift else "no drift beyond the noise"
    figure.suptitle(f"{title}\n{verdict}: largest |z| {drift.statistic:.3g}, threshold "
                    f"{drift.threshold:.3g}", fontsize=9)
    return figure
