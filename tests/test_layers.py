"""The package's layers: the core and every pure module import without the adapters'
libraries, and the import graph has no cycle."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

from twin.distribution import EXTRAS

PACKAGE = Path(__file__).resolve().parents[1] / "twin"

ADAPTERS = {
    # MuJoCo: the digital twin (poses and touches are found on it, with its collisions and line
    # of sight; compensation is verified on it), and the MJCF export built from it.
    "twin.sim", "twin.sim.builder", "twin.sim.equilibrium", "twin.sim.mujoco_twin",
    "twin.sim.poses", "twin.sim.touches", "twin.sim.simulate", "twin.sim.verification",
    "twin.export.mjcf",
    # Pinocchio.
    "twin.export.pinocchio", "twin.export.urdf",
    # Rerun: the recording and what it logs.
    "twin.viz.recording", "twin.viz.sinks", "twin.viz.scene", "twin.viz.calibration_log",
    "twin.viz.blueprint", "twin.viz.writer",
    # pyserial, minimalmodbus: the encoder drivers.
    "twin.hardware.encoders.ascii", "twin.hardware.encoders.modbus",
}
"""Modules that import an adapter's library by design."""
TOP = {"twin.study.trial", "twin.study.runner", "twin.study.check", "twin.study.junit",
       "twin.testing", "twin.__main__"}
"""Modules that wire the twin into studies and checks (and run them): they import MuJoCo."""


def modules() -> dict[str, Path]:
    """Every module of the package: its dotted name and its file."""
    found = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return found


def test_pure_modules_import_without_the_adapters_libraries() -> None:
    """In an interpreter where mujoco, pinocchio, rerun, serial, minimalmodbus, pymodbus and
    dask cannot be imported, every module but the adapters and the top imports."""
    pure = [name for name in modules() if name not in ADAPTERS | TOP]
    code = (
        "import importlib, json, sys\n"
        f"for name in {sorted(EXTRAS)!r}:\n    sys.modules[name] = None\n"
        "failed = {}\n"
        f"for name in {pure!r}:\n"
        "    try:\n        importlib.import_module(name)\n"
        "    except ImportError as exc:\n        failed[name] = exc.name\n"
        "print(json.dumps(failed))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    failed = json.loads(done.stdout)
    assert failed == {}
    assert set(ADAPTERS | TOP) <= set(modules()), "a listed module is gone"


def _imports(name: str, path: Path, modules: set[str]) -> set[str]:
    """The package's modules ``name`` imports, anywhere in it (functions too), except under
    ``if TYPE_CHECKING:``; ``from pkg import mod`` counts as importing ``pkg.mod``."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    typing_only = {id(node) for block in ast.walk(tree) if isinstance(block, ast.If)
                   and "TYPE_CHECKING" in ast.unparse(block.test) for node in ast.walk(block)}
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(tree):
        if id(node) in typing_only:
            continue
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*parts, base] if base else parts)
            found |= {f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base
                      for a in node.names}
    return {module for module in found if module in modules and module != name}


def test_the_import_graph_has_no_cycle() -> None:
    """No module imports, directly or through others, a module that imports it back."""
    files = modules()
    graph = {name: _imports(name, path, set(files)) for name, path in files.items()}
    done: set[str] = set()

    def cycle(trail: list[str]) -> list[str] | None:
        """A cycle reachable from the last module of ``trail`` (the modules being visited)."""
        for child in sorted(graph[trail[-1]]):
            if child in trail:
                return [*trail[trail.index(child):], child]
            if child not in done:
                found = cycle([*trail, child])
                if found:
                    return found
        done.add(trail[-1])
        return None

    for name in files:
        found = None if name in done else cycle([name])
        assert found is None, "import cycle: " + " -> ".join(found or [])
