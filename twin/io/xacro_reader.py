"""xacro in: a robot description written in xacro, expanded to its URDF by the ``xacro`` package
(PyPI, no ROS installation needed) and read as a URDF (:mod:`twin.io.urdf_reader`).

An adapter: it imports ``xacro`` when a ``.xacro`` file is read. Arguments are given as
``NAME:=VALUE`` (``--xacro-arg``), as on xacro's own command line; relative paths in the
description resolve from its folder, as xacro does.

``$(find PKG)`` needs to know where packages are. With ROS 2 sourced xacro asks
``ament_index_python`` itself; without it twin looks ``PKG`` up where ROS does: in each folder of
``AMENT_PREFIX_PATH`` (its ``share/PKG``) and of ``ROS_PACKAGE_PATH`` (a folder that is the
package — it holds a ``package.xml`` naming it — or holds such a folder). So a description from a
ROS package (``ur_description``'s ``ur.urdf.xacro``) expands once those packages are on one of the
two paths; a package found nowhere is one line naming it. ``package://`` mesh references are left
as they are (twin reads no meshes).
"""

from __future__ import annotations

import contextlib
import io
import os
import re
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path

from twin.errors import InputError
from twin.io.paths import read_text

WHAT = "a xacro robot description"
XACRO_SUFFIX = ".xacro"
_ARGUMENT = re.compile(r"([A-Za-z_][A-Za-z0-9_]*):=(.*)", re.S)


def parse_xacro_args(values: Sequence[str] | None) -> dict[str, str]:
    """``NAME:=VALUE`` flags as a mapping.

    Raises:
        InputError: for a value that is not ``NAME:=VALUE``, or a name twice.
    """
    found: dict[str, str] = {}
    for value in values or ():
        match = _ARGUMENT.fullmatch(value)
        if match is None:
            raise InputError(f"{value!r}", "NAME:=VALUE, as xacro takes its arguments",
                             source="--xacro-arg")
        if match[1] in found:
            raise InputError(f"{match[1]} twice", "each argument once", source="--xacro-arg")
        found[match[1]] = match[2]
    return found


def _package_xml_names(folder: Path) -> str | None:
    manifest = folder / "package.xml"
    if not manifest.is_file():
        return None
    match = re.search(r"<name>\s*([^<\s]+)\s*</name>", manifest.read_text(errors="replace"))
    return match[1] if match else folder.name


def find_package(name: str) -> Path:
    """A ROS package's folder from ``AMENT_PREFIX_PATH`` and ``ROS_PACKAGE_PATH``.

    Raises:
        InputError: naming the package when neither path has it.
    """
    for prefix in filter(None, os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep)):
        share = Path(prefix) / "share" / name
        if share.is_dir():
            return share
    for entry in filter(None, os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep)):
        root = Path(entry)
        if _package_xml_names(root) == name:
            return root
        if root.is_dir():
            for child in sorted(root.iterdir()):
                if child.is_dir() and _package_xml_names(child) == name:
                    return child
    raise InputError(f"$(find {name}): no package {name!r}", "its folder on AMENT_PREFIX_PATH "
                     "(share/NAME) or ROS_PACKAGE_PATH (a folder with its package.xml)",
                     source="--robot")


@contextlib.contextmanager
def _packages_found_by_twin() -> Iterator[None]:
    """Let xacro's ``$(find)`` use :func:`find_package` when ament_index_python is missing."""
    import xacro.substitution_args as substitution

    try:
        import ament_index_python  # noqa: F401
    except ImportError:
        pass
    else:
        yield
        return
    saved, saved_eval = substitution._eval_find, substitution._eval_dict["find"]

    def find(name: str) -> str:
        return str(find_package(name))

    substitution._eval_find = find
    substitution._eval_dict["find"] = find
    try:
        yield
    finally:
        substitution._eval_find = saved
        substitution._eval_dict["find"] = saved_eval


def expand_xacro(path: str | Path, arguments: Mapping[str, str]) -> str:
    """The URDF text a xacro file expands to with the arguments given.

    Raises:
        InputError: for a file xacro cannot expand (its own message, in one line), or a
            ``$(find)`` package found nowhere.
    """
    import xacro

    path = Path(path)
    read_text(path, WHAT)  # the one reader's checks: a regular, readable, bounded file
    # xacro prints its warnings and errors to stderr as well: kept off the terminal.
    with _packages_found_by_twin(), contextlib.redirect_stderr(io.StringIO()):
        try:
            document = xacro.process_file(str(path), mappings=dict(arguments), verbosity=0)
        except InputError:
            raise
        except Exception as exc:  # xacro raises bare Exceptions, XML and YAML errors alike
            message = " ".join(str(exc).split()) or type(exc).__name__
            raise InputError(f"a description xacro cannot expand ({message})", WHAT,
                             source=path) from None
    return str(document.toprettyxml(indent="  "))
