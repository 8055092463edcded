"""The installed distribution: its name on the package index, its version and its extras.

The import name is ``twin``; the distribution is published as :data:`NAME`, because ``twin``
is taken on PyPI. The core install (numpy, scipy, matplotlib) calibrates, identifies, plans,
compensates and exports D-H tables; each adapter's library comes with an extra
(:data:`EXTRAS`), and a command that needs a missing one says which to install.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _metadata_version

from twin.errors import InputError

NAME = "cabletwin"
"""The distribution's name on the package index (``pip install cabletwin``)."""
EXTRAS = {
    "mujoco": "sim",
    "pinocchio": "pinocchio",
    "rerun": "viz",
    "serial": "hardware",
    "minimalmodbus": "hardware",
    "pymodbus": "hardware",
    "xacro": "ros",
    "ruamel": "ros",
    "requests": "hardware",
    "urllib3": "hardware",
    "rosbags": "ros",
    "dask": "cluster",
    "distributed": "cluster",
}
"""The extra that installs each adapter library, by its top-level import name."""


def version() -> str:
    """The installed version, from the distribution's metadata, or why there is none."""
    try:
        return _metadata_version(NAME)
    except PackageNotFoundError:
        # Run from a source tree that was never installed (PYTHONPATH=.): say so rather than
        # invent a number.
        return "(not installed: no metadata)"


class MissingExtraError(InputError):
    """An adapter library that is not installed, and the extra that installs it.

    Attributes:
        module: The library's top-level import name (``mujoco``).
        extra: The extra of :data:`NAME` that installs it (``sim``).
    """

    def __init__(self, module: str, extra: str, *, source: str | None = None) -> None:
        self.module = module
        self.extra = extra
        super().__init__(f"no module {module!r}", f"the optional extra that installs it: "
                         f"pip install '{NAME}[{extra}]'", source=source)


def missing_extra(exc: ImportError, *, source: str | None = None) -> MissingExtraError | None:
    """The extra to install for an ``ImportError`` of an adapter library, or None if the
    error is about anything else (a broken install of the core is not a missing extra).

    Libraries that wrap their own ``ImportError`` (``dask.distributed``) keep the original as
    the cause, so the chain is searched.
    """
    error: BaseException | None = exc
    while error is not None:
        name = getattr(error, "name", None) or ""
        extra = EXTRAS.get(name.partition(".")[0])
        if extra is not None:
            return MissingExtraError(name.partition(".")[0], extra, source=source)
        error = error.__cause__ or error.__context__
    return None
