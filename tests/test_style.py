"""The style guide's measurable rules: no function over 80 lines."""

from __future__ import annotations

import ast
import functools
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "twin"
MAX_FUNCTION_LINES = 80
"""From ``def`` to the function's last line, docstring and comments included."""


@functools.cache
def _nodes(path: Path) -> tuple[ast.AST, ...]:
    """Every node of the module at ``path``, parsed and walked once for the checks below."""
    return tuple(ast.walk(ast.parse(path.read_text(encoding="utf-8"))))


def long_functions(root: Path, limit: int = MAX_FUNCTION_LINES) -> list[str]:
    """``path:line name (n lines)`` (the path relative to ``root``) for every function or
    method under ``root`` longer than ``limit`` lines, nested ones too."""
    found = []
    for path in sorted(root.rglob("*.py")):
        for node in _nodes(path):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = (node.end_lineno or node.lineno) - node.lineno + 1
                if lines > limit:
                    found.append(f"{path.relative_to(root).as_posix()}:{node.lineno} "
                                 f"{node.name} ({lines} lines)")
    return sorted(found)


@pytest.mark.slow
def test_no_function_is_over_80_lines() -> None:
    """Every function of the package, from ``def`` to its last line, is at most 80 lines: a
    long one is split into the steps it takes (a parser into a table of small readers)."""
    assert long_functions(PACKAGE) == []


def test_the_check_sees_a_long_function(tmp_path: Path) -> None:
    """The check counts from ``def`` to the last line, methods and nested functions too: 80
    lines pass, 81 do not."""
    def body(lines: int, indent: str) -> str:
        return "".join(f"{indent}x{i} = {i}\n" for i in range(lines))

    (tmp_path / "long.py").write_text(
        "def fits():\n" + body(79, "    ")
        + "class A:\n    def method(self):\n" + body(80, "        ")
        + "def outer():\n    def inner():\n" + body(80, "        "))
    assert long_functions(tmp_path) == ["long.py:163 outer (82 lines)",
                                        "long.py:164 inner (81 lines)",
                                        "long.py:82 method (81 lines)"]


KINDS_PACKAGE = PACKAGE / "kinds"


def _literals(node: ast.AST) -> set[str]:
    """The strings a comparison's side holds: a string, or the strings of a tuple, list or
    set of them."""
    items = node.elts if isinstance(node, ast.Tuple | ast.List | ast.Set) else [node]
    return {item.value for item in items
            if isinstance(item, ast.Constant) and isinstance(item.value, str)}


def kind_branches(root: Path, names: set[str], skip: Path | None = None) -> list[str]:
    """``path:line code`` for every comparison or ``case`` under ``root`` (outside ``skip``)
    that names a measurement kind: ``data.kind == "length"``, ``kind in ("point", …)``."""
    found = []
    for path in sorted(root.rglob("*.py")):
        if skip is not None and path.is_relative_to(skip):
            continue
        for node in _nodes(path):
            if isinstance(node, ast.Compare):
                named = set().union(*(_literals(side) for side in (node.left, *node.comparators)))
            elif isinstance(node, ast.MatchValue):
                named = _literals(node.value)
            else:
                continue
            if named & names:
                found.append(f"{path.relative_to(root).as_posix()}:{node.lineno} "
                             f"{ast.unparse(node)}")
    return found


def test_no_branch_on_a_kind_name_outside_the_kinds() -> None:
    """Nothing outside twin/kinds asks which kind a measurement is: each kind owns its columns,
    residuals, start, truth in the twin, predictions, report lines and drawing
    (twin.kinds.base.Kind), so that a new kind is one module and its registration."""
    from twin.kinds import KINDS

    assert kind_branches(PACKAGE, set(KINDS), skip=KINDS_PACKAGE) == []


def test_the_kind_check_sees_a_branch(tmp_path: Path) -> None:
    """The check finds a kind's name compared, tested for membership or matched; not another
    string, nor a kind compared with a name held in a variable."""
    (tmp_path / "a.py").write_text(
        'if data.kind == "length":\n    pass\n'
        'x = kind in ("point", "other")\n'
        'match kind:\n    case "length":\n        pass\n'
        'y = data.kind == kind.name\n'
        'z = token.kind == "number"\n')
    assert kind_branches(tmp_path, {"length", "point"}) == [
        "a.py:1 data.kind == 'length'", "a.py:3 kind in ('point', 'other')", "a.py:5 'length'"]
