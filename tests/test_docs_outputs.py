"""Doc examples write only under out/: every `twin` command line in README.md, docs/ and the
examples' READMEs names its outputs (`--out`, `--json`, `--map`, `--junit`, `--rerun-save`,
`--pose-file`) under `out/`, or as a placeholder in capitals (DIR, OUT.json), unless the line
shows a refusal (the next line an error: nothing is written)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")),
         *sorted((ROOT / "examples").glob("*/README.md"))]
OUTPUT = re.compile(r"--(?:out|json|map|junit|rerun-save|pose-file)[ =](\S+)")
PLACEHOLDER = re.compile(r"[\"']?[A-Z][A-Z0-9_.-]*(?:\.\w+)?[\"']?$|.*[A-Z]{3,}")


def _commands(page: Path) -> list[tuple[int, str]]:
    """The `twin …` command lines of a page's code blocks (continuations joined), each with
    its line number, that are not followed by an error."""
    lines = page.read_text(encoding="utf-8").splitlines()
    found, inside = [], False
    for number, line in enumerate(lines):
        if line.lstrip().startswith("```"):
            inside = not inside
            continue
        text = line.strip().removeprefix("$ ")
        if not inside or not re.match(r"(\S*/)?twin |\$T ", text):
            continue
        end = number
        while lines[end].rstrip().endswith("\\") and end + 1 < len(lines):
            end += 1
            text = text.rstrip("\\") + " " + lines[end].strip()
        following = lines[end + 1].strip() if end + 1 < len(lines) else ""
        if not following.startswith("twin: error"):
            found.append((number + 1, text))
    return found


@pytest.mark.parametrize("page", PAGES, ids=lambda page: page.name)
def test_doc_examples_write_only_under_out(page: Path) -> None:
    stray = [f"{page.name}:{number}: {value}" for number, text in _commands(page)
             for value in OUTPUT.findall(text.split(" #")[0])
             if not value.strip("\"'").startswith("out/") and not PLACEHOLDER.match(value)]
    assert not stray, stray
