"""The installed distribution: its name on the package index, its version, its extras, and
the one registry every family of plug-ins uses.

The import name is ``twin``; the distribution is published as :data:`NAME`, because ``twin``
is taken on PyPI. The core install (numpy, scipy, matplotlib) calibrates, identifies, plans,
compensates and exports D-H tables; each adapter's library comes with an extra
(:data:`EXTRAS`), and a command that needs a missing one says which to install.

Each family (solvers, measurement kinds, unknown groups, encoders, robot sources, study
executors, export formats) is a subpackage with one interface, one module per member and one
:class:`Registry` of its members by name: the library looks members up there, the CLI lists
them from there, and a new member is one module and one line in its family's registry. A member
whose module needs an extra's library is registered :class:`Lazy` and imported when first
asked for.
"""

from __future__ import annotations

import importlib
import importlib.util
import os
from collections.abc import Callable, Iterable, Iterator, Mapping
from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _metadata_version
from typing import Any, NamedTuple, TypeVar

from twin.choices import KERNEL_VARIABLE, KERNELS
from twin.errors import InputError, UnknownChoiceError

Member = TypeVar("Member")

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
    "numba": "fast",
    "llvmlite": "fast",
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


def kernel_choice() -> str:
    """The kernel :data:`~twin.choices.KERNEL_VARIABLE` chooses (``auto`` when unset), checked
    without importing it: every command checks it before it runs, so that a study refuses it
    before its folder exists, not at its first trial.

    Raises:
        UnknownChoiceError: for a value that is not one of :data:`~twin.choices.KERNELS` (a
            typo had run the numpy path unsaid).
        MissingExtraError: for ``numba`` where numba is not installed (the extra ``fast``).
    """
    mode = os.environ.get(KERNEL_VARIABLE, "auto")
    if mode not in KERNELS:
        raise UnknownChoiceError("kernel", mode, KERNELS, source=KERNEL_VARIABLE)
    if mode == "numba" and importlib.util.find_spec("numba") is None:
        raise MissingExtraError("numba", EXTRAS["numba"], source=KERNEL_VARIABLE)
    return mode


class Lazy(NamedTuple):
    """A registry member imported when first asked for: ``"package.module:attribute"``."""

    target: str


class Registry(Mapping[str, Member]):
    """The members of one plug-in family by name, in the order given (the order lists show and,
    for unknown groups, the order x lays them out in).

    A :class:`~collections.abc.Mapping`: ``registry[name]`` (a ``KeyError`` for an unknown
    name, as any mapping), ``name in registry``, iteration over the names. :meth:`lookup` is
    the user-facing way: it accepts aliases and raises :class:`~twin.errors.UnknownChoiceError`
    listing the choices.

    Args:
        kind: What a member is, for messages (``method``, ``export format``).
        members: Each member by name, or its :class:`Lazy` import path.
        aliases: Other names of members (``{"m2": "lm"}``), shown beside them in
            :meth:`choices`.
        ignore_case: Whether :meth:`lookup` folds case (and strips blanks).
    """

    def __init__(self, kind: str, members: Mapping[str, Member | Lazy], *,
                 aliases: Mapping[str, str] | None = None, ignore_case: bool = False) -> None:
        self.kind = kind
        self._members = dict(members)
        self._aliases = dict(aliases or {})
        unknown = set(self._aliases.values()) - set(self._members)
        if unknown:
            raise ValueError(f"{kind} aliases of no member: {sorted(unknown)}")
        self.ignore_case = ignore_case

    def __getitem__(self, name: str) -> Member:
        member = self._members[name]
        if isinstance(member, Lazy):
            # An extra's missing library rises as ImportError, which the CLI turns into the
            # extra to install (missing_extra), naming the command.
            module, _, attribute = member.target.partition(":")
            member = getattr(importlib.import_module(module), attribute)
            self._members[name] = member
        return member

    def __iter__(self) -> Iterator[str]:
        return iter(self._members)

    def __len__(self) -> int:
        return len(self._members)

    def alias(self, name: str) -> str:
        """The alias of member ``name`` (the paper's ``m2`` of ``lm``), or "" if it has none."""
        return next((alias for alias, member in self._aliases.items() if member == name), "")

    def choices(self) -> list[str]:
        """``name (alias)`` (or ``name``) for every member, for help texts and messages."""
        aliases = {name: alias for alias, name in self._aliases.items()}
        return [f"{name} ({aliases[name]})" if name in aliases else name for name in self]

    def lookup(self, name: str, *, source: str | None = None, also: Iterable[str] = ()
               ) -> Member:
        """The member called or aliased ``name``.

        Args:
            name: A member's name or alias.
            source: The flag or file the name came from, for the message.
            also: Further choices the caller accepts beside the members (``all``), listed.

        Raises:
            UnknownChoiceError: listing :meth:`choices` (and ``also``).
            ImportError: for a lazy member whose extra is not installed.
        """
        key = name.strip().lower() if self.ignore_case else name
        key = self._aliases.get(key, key)
        if key not in self._members:
            raise UnknownChoiceError(self.kind, name, [*self.choices(), *also], source=source)
        return self[key]


def lazy_exports(package: str, homes: Mapping[str, Iterable[str]]) -> Callable[[str], Any]:
    """A package's module ``__getattr__`` (PEP 562) that imports each public name from its
    module when first read, so that importing the package loads none of them: the command
    line's help then needs no numpy. Declare the names for type checkers under
    ``if TYPE_CHECKING:``.

    Args:
        package: The package's ``__name__``, for the message of an unknown name.
        homes: The names each module holds, by the module's dotted name.
    """
    home = {name: module for module, names in homes.items() for name in names}

    def attribute(name: str) -> Any:
        module = home.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        setattr(importlib.import_module(package), name, value)
        return value

    return attribute
