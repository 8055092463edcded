"""Matplotlib, set up once for every figure `twin` draws.

Figures are drawn on the Agg backend (no display, no window, the same pixels on a server as on
a desktop) and written as PNG at :data:`DPI`, atomically (:mod:`twin.io.atomic`), like every
other output. Matplotlib is imported on first use: commands that draw nothing do not pay for it.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

from twin.io.atomic import write_atomic

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
