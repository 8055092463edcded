"""The one plotting set-up: Agg, PNGs at one resolution, written atomically."""

from __future__ import annotations

from pathlib import Path

import matplotlib
import pytest
from matplotlib.image import imread

from twin.errors import InputError
from twin.io.png import DPI, save_png
from twin.report.plots import pyplot


def test_png_has_the_resolution_and_replaces_the_file_whole(tmp_path: Path) -> None:
    """A 2 × 1 inch figure is a (DPI, 2·DPI) PNG that reads back; a second one replaces it
    through a temporary file that does not stay; the figure is closed."""
    plt = pyplot()
    assert matplotlib.get_backend().lower() == "agg"
    path = tmp_path / "figure.png"
    for _ in range(2):
        figure, axes = plt.subplots(figsize=(2, 1))
        axes.plot([0, 1], [0, 1])
        save_png(figure, path)
        assert not plt.fignum_exists(figure.number)
    assert imread(path).shape[:2] == (DPI, 2 * DPI)
    assert [p.name for p in tmp_path.iterdir()] == ["figure.png"]


def test_png_onto_a_folder_is_refused(tmp_path: Path) -> None:
    """A figure is an output like any other: a folder in its place is an InputError."""
    figure, _ = pyplot().subplots()
    with pytest.raises(InputError, match="a directory"):
        save_png(figure, tmp_path)


def test_study_metrics_start_at_zero(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Fig. 3's bars are mean ± std of quantities that are never negative: a skewed time whose
    std exceeds its mean is cut at zero, not drawn below it."""
    from twin.study import figures

    stats = {"rmse": {"mean": 0.3, "std": 0.05}, "mae": {"mean": 0.2, "std": 0.04},
             "max": {"mean": 0.7, "std": 0.2}, "seconds": {"mean": 0.005, "std": 0.02}}
    drawn = figures.fig_metrics({"before": stats, "lm": stats}, "title")
    lows = [axis.get_ylim()[0] for axis in drawn.axes]
    pyplot().close(drawn)
    assert len(lows) == 4 and min(lows) >= 0.0, lows
