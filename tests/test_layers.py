"""The package's layers: one import rule per subpackage (imports point inward), the core and
every pure module import without the adapters' libraries, and the import graph has no cycle."""

from __future__ import annotations

import ast
import functools
import json
import subprocess
import sys
from pathlib import Path

import pytest

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
    # numba: the compiled kernels (the numpy and scipy paths run without them).
    "twin.geometry.compiled", "twin.solvers.compiled",
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


@pytest.mark.slow
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


@functools.cache
def import_graph() -> dict[str, frozenset[str]]:
    """The package's modules each module imports (:func:`_imports`), parsed once for the
    tests that read it."""
    files = modules()
    return {name: frozenset(_imports(name, path, set(files))) for name, path in files.items()}


@pytest.mark.slow
def test_the_import_graph_has_no_cycle() -> None:
    """No module imports, directly or through others, a module that imports it back."""
    graph = import_graph()
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

    for name in graph:
        found = None if name in done else cycle([name])
        assert found is None, "import cycle: " + " -> ".join(found or [])


FOUNDATIONS = {"twin.errors", "twin.units", "twin.arrays", "twin.distribution", "twin.choices",
               "twin.report.display", "twin.waiting"}
"""Imported by every layer: one exception root, SI conversions, the array type, the
distribution's extras and plug-in registry, how a number is shown, and how a main thread waits
for its stop."""
VALUES = {"twin.robot", "twin.rig", "twin.dataset"}
SPINE = {"twin.model", "twin.problem", "twin.loss", "twin.stopping"}
HELPERS = {"twin": "package", "twin.__main__": "main", "twin.synthetic": "synthetic",
           "twin.testing": "testing"}
"""The root's public helpers, each its own layer."""


def layer(name: str) -> str:
    """The layer of a module: a root group or its subpackage."""
    if name in FOUNDATIONS:
        return "foundations"
    if name in VALUES:
        return "values"
    if name in SPINE:
        return "spine"
    if name in HELPERS:
        return HELPERS[name]
    return name.split(".")[1]


_BELOW_FAMILIES = {"foundations", "geometry", "values"}
_FAMILIES = {"kinds", "unknowns"}
_CORE = {*_BELOW_FAMILIES, *_FAMILIES, "spine", "solvers", "analysis", "design", "compensation",
         "calibration"}
RULES: dict[str, set[str]] = {
    "foundations": set(),
    # Pure numpy geometry: nothing of the model above it.
    "geometry": {"foundations"},
    "values": {"foundations", "geometry"},
    # A family member sees the values it acts on; the model assembles the families.
    "kinds": _BELOW_FAMILIES,
    "unknowns": _BELOW_FAMILIES,
    "spine": {*_BELOW_FAMILIES, *_FAMILIES},
    "analysis": {*_BELOW_FAMILIES, *_FAMILIES, "spine"},
    # lm-base fits the base parameters analysis names.
    "solvers": {*_BELOW_FAMILIES, *_FAMILIES, "spine", "analysis"},
    # Design and compensation take their MuJoCo sampler or twin from the caller: no sim.
    "design": {*_BELOW_FAMILIES, *_FAMILIES, "spine", "analysis"},
    "compensation": {*_BELOW_FAMILIES, *_FAMILIES, "spine", "analysis"},
    "calibration": {*_BELOW_FAMILIES, *_FAMILIES, "spine", "solvers", "analysis", "design"},
    # What a user reads is made from the core's values; files are written by the caller.
    "report": _CORE,
    # Every file format, for every room above the core.
    "io": _CORE,
    # Pure descriptions of what the twin simulates, read through io's one config reader.
    "scenario": {*_CORE, "io"},
    # The adapters: each imports the core, io and what it adapts, never the top.
    "sim": {*_CORE, "io", "scenario"},
    "export": {*_CORE, "io", "sim"},
    "viz": {*_CORE, "io", "report"},
    "hardware": {*_CORE, "io", "scenario", "sim"},
    # The top wires everything.
    "study": {*_CORE, "io", "report", "scenario", "sim"},
    "cli": {*_CORE, "io", "report", "scenario", "sim", "export", "viz", "hardware", "study",
            "testing"},
    "package": {*_CORE, "io"},
    "synthetic": _CORE,
    "testing": {"study"},
    "main": {"cli"},
}
"""The layers each layer may import besides its own."""


def test_every_layer_imports_only_what_its_rule_allows() -> None:
    """Each module's imports (outside ``if TYPE_CHECKING:``) lie in its own layer or in the
    layers its rule allows; every module of every subpackage has a rule."""
    files = modules()
    assert {layer(name) for name in files} == set(RULES), "a layer without a rule, or a rule " \
        "without a layer"
    broken = sorted(f"{name} -> {dep}" for name, imported in import_graph().items()
                    for dep in imported
                    if layer(dep) != layer(name) and layer(dep) not in RULES[layer(name)])
    assert broken == []


def test_the_core_imports_no_io_and_no_adapter() -> None:
    """The rules keep io, the scenario, the adapters and the top out of the core, and MuJoCo
    out of design and compensation (a check of the rules themselves)."""
    outside = {"io", "scenario", "sim", "hardware", "viz", "export", "study", "cli", "report"}
    assert all(not RULES[name] & outside for name in _CORE)
    assert "sim" not in RULES["design"] | RULES["compensation"]
