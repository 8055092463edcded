"""PNG figures: every figure `twin` draws (:mod:`twin.report.plots`) is written here, at one
resolution and atomically (:mod:`twin.io.atomic`), like every other output."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

from twin.io.atomic import write_atomic

DPI = 120
"""Resolution of every PNG, dots per inch."""


def save_png(figure: Any, path: str | Path) -> None:
    """Write ``figure`` to ``path`` as a PNG at :data:`DPI`, atomically, and close it.

    Every figure is laid out by matplotlib's constrained layout as it is drawn: one draw. A
    ``tight_layout`` and a page cropped to what is drawn drew each of a study's figures twice
    and measured it a third time (3.6 s of a 2-trial study's report, of which the figures
    were all).

    Args:
        figure: A matplotlib figure from :func:`twin.report.plots.pyplot`, made with
            ``layout="constrained"``.
        path: The PNG file.

    Raises:
        InputError: if ``path`` is not a valid output or cannot be written.
    """
    import matplotlib.pyplot as plt

    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=DPI)
    plt.close(figure)
    write_atomic(path, buffer.getvalue())
