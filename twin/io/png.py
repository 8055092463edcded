"""PNG figures: every figure `twin` draws (:mod:`twin.report.plots`) is written here, at one
resolution and atomically (:mod:`twin.io.atomic`), like every other output."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

from twin.io.atomic import write_atomic

DPI = 120
"""Resolution of every PNG, dots per inch."""


def save_png(figure: Any, path: str | Path, *, tight: bool = False) -> None:
    """Write ``figure`` to ``path`` as a PNG at :data:`DPI`, atomically, and close it.

    Args:
        figure: A matplotlib figure from :func:`twin.report.plots.pyplot`.
        path: The PNG file.
        tight: Crop the page to what is drawn (for figures laid out without
            ``layout="constrained"``).

    Raises:
        InputError: if ``path`` is not a valid output or cannot be written.
    """
    import matplotlib.pyplot as plt

    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=DPI, bbox_inches="tight" if tight else None)
    plt.close(figure)
    write_atomic(path, buffer.getvalue())
