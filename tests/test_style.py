"""The style guide's measurable rules: no function over 80 lines."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "twin"
MAX_FUNCTION_LINES = 80
"""From ``def`` to the function's last line, docstring and comments included."""


def long_functions(root: Path, limit: int = MAX_FUNCTION_LINES) -> list[str]:
    """``path:line name (n lines)`` (the path relative to ``root``) for every function or
    method under ``root`` longer than ``limit`` lines, nested ones too."""
    found = []
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = (node.end_lineno or node.lineno) - node.lineno + 1
                if lines > limit:
                    found.append(f"{path.relative_to(root).as_posix()}:{node.lineno} "
                                 f"{node.name} ({lines} lines)")
    return sorted(found)


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
