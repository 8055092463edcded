"""The installed distribution: its name on the package index and its version.

The import name is ``twin``; the distribution is published as :data:`NAME`, because ``twin``
is taken on PyPI.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _metadata_version

NAME = "cabletwin"
"""The distribution's name on the package index (``pip install cabletwin``)."""


def version() -> str:
    """The installed version, from the distribution's metadata, or why there is none."""
    try:
        return _metadata_version(NAME)
    except PackageNotFoundError:
        # Run from a source tree that was never installed (PYTHONPATH=.): say so rather than
        # invent a number.
        return "(not installed: no metadata)"
