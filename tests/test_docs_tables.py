"""The docs' tables of figures are generated: each block exists, is filled and names its commit."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[1] / "docs"
BLOCK = re.compile(r"<!-- BEGIN GENERATED (?P<name>[\w-]+) -->\n(?P<body>.*?)"
                   r"<!-- END GENERATED (?P=name) -->", re.DOTALL)
EXPECTED = {
    "methods.md": {"protocols", "m9-bipso-stage", "bench-solvers", "bench-calibration",
                   "error-models", "bench-extended"},
    "studies.md": {"paper-replica", "regimes", "bench-study", "bench-speed", "check-base",
                   "check-baseline"},
    "robots.md": {"parametrisation"},
    "measurements.md": {"rigs", "stations", "limits", "noise-inputs", "pose-table",
                        "pose-transcript", "plane-table", "plane-transcript", "unknown-port",
                        "sessions", "scale-table", "scale-transcript", "drift-transcript",
                        "drift-table", "thermal-transcript", "thermal-table"},
    "twin.md": {"paper-rig", "demo-transcript"},
    "identifiability.md": {"unknown-sets", "held", "bench-design", "twin-check",
                           "identify-transcript"},
    "../README.md": {"readme-calibrate"},
}


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_generated_blocks_are_filled_and_stamped(name: str) -> None:
    """Every block `make docs` writes is there, not empty, and says the commit it was measured
    at; outside the blocks no table row carries measured figures (two or more numbers with three
    decimals; a threshold such as 0.001 mm² in a definition is one)."""
    text = (DOCS / name).read_text(encoding="utf-8")
    blocks = {match["name"]: match["body"] for match in BLOCK.finditer(text)}
    assert set(blocks) == EXPECTED[name]
    for block, body in blocks.items():
        assert re.search(r"Measured at commit `[0-9a-f]{7,}(\+changes)?` on \d{4}-\d{2}-\d{2}",
                         body), block
        assert body.count("\n") > 3, block
    outside = BLOCK.sub("", text)
    table_rows = [line for line in outside.splitlines() if line.startswith("|")]
    measured = [row for row in table_rows if len(re.findall(r"\d\.\d{3}", row)) >= 2]
    assert not measured, measured[:3]
