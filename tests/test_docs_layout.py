"""The docs keep the design and its history apart: docs/benchmarks.md is what `make bench`
writes (every section heading one a bench script writes, and short), and the measurements
that chose the design are records in docs/decisions/, each with its decision and date."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MOST_LINES = 300  # a page of results, not a lab notebook


def test_benchmarks_holds_only_what_make_bench_writes():
    text = (ROOT / "docs" / "benchmarks.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) <= MOST_LINES
    scripts = "".join(p.read_text(encoding="utf-8") for p in (ROOT / "bench").glob("*.py"))
    headings = re.findall(r"^##+ .*$", text, re.M)
    assert headings, "no sections"
    for heading in headings:
        assert f'"{heading}"' in scripts, f"{heading!r}: no bench script writes it"


def test_every_decision_record_says_what_when_and_is_listed():
    folder = ROOT / "docs" / "decisions"
    index = (folder / "README.md").read_text(encoding="utf-8")
    records = sorted(p for p in folder.glob("*.md") if p.name != "README.md")
    assert len(records) >= 10
    for path in records:
        text = path.read_text(encoding="utf-8")
        assert re.search(r"^Date: 20\d\d-\d\d-\d\d", text, re.M), path.name
        assert "\n## Decision\n" in text, path.name
        assert f"]({path.name})" in index, f"{path.name} is not in the index"
