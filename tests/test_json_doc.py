"""docs/json.md is the one description of `calibc solve --json`: its tables are checked against
what the command writes (every "always" key present, no key undocumented, no documented key
that no case writes, but those the cases cannot reach)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from click.testing import CliRunner

from calib_dsl.cli import main
from tests.inner.test_shave import write_circle

ROOT = Path(__file__).resolve().parents[1]
ARM = ROOT / "models" / "examples" / "planar_arm.cal"
UNREACHED = {"prior"}  # a domain `lsq +- w`: the UR10 models (tests/test_ur10.py)


def documented(section: str) -> dict[str, str]:
    """key -> its "when" column, from the table under `## section`."""
    text = (ROOT / "docs" / "json.md").read_text(encoding="utf-8")
    body = text.split(f"## {section}\n", 1)[1].split("\n## ", 1)[0]
    return {m.group(1): m.group(2).strip()
            for m in re.finditer(r"^\| `(\w+)` \| ([^|]+) \|", body, re.M)}


def written(tmp_path: Path, model: Path, *args: str) -> dict:
    out = tmp_path / "r.json"
    res = CliRunner().invoke(main, ["solve", str(model), "--json", str(out), *args])
    assert res.exit_code in (0, 1), res.output
    return json.loads(out.read_text(encoding="utf-8"))


@pytest.fixture(scope="module")
def cases(tmp_path_factory) -> list[dict]:
    tmp = tmp_path_factory.mktemp("json")
    (tmp / "w.csv").write_text("x,v\n0,0.1\n1,0.3\n2,0.5\n3,2.9\n")  # the last row is off
    bad = tmp / "bad.cal"
    bad.write_text('param a in [0, 1]; param b in [0, 1];\n'
                   'table m = "w.csv" { x : +- 1e-9; v : +- 0.01; }\n'
                   "for k in 1..rows(m) { a * m.x[k] + b == m.v[k]; }\n")
    free = tmp / "free.cal"
    free.write_text("var x in [0, 1];\nvar y in [0, 1];\nvar z in [3, 4];\nz == x + y;\n")
    write_circle(tmp)  # a result looser than its inner bounds: shaved
    return [written(tmp, ARM, "--lsq", "--residuals"), written(tmp, ARM, "--strategy", "hc4"),
            written(tmp, bad), written(tmp, free), written(tmp, bad, "--outliers", "1"),
            written(tmp, tmp / "circle.cal", "--shave", "1")]


def test_the_top_level_is_as_documented(cases):
    doc = documented("Top level")
    always = {k for k, when in doc.items() if when == "always"}
    seen: set[str] = set()
    for data in cases:
        assert always <= set(data) <= set(doc), set(data) ^ set(doc)
        seen |= set(data)
    assert set(doc) - seen <= UNREACHED


def test_each_parameter_is_as_documented(cases):
    doc = documented("Per parameter")
    always = {k for k, when in doc.items() if when == "always"}
    seen: set[str] = set()
    for data in cases:
        for p in data["parameters"].values():
            assert always <= set(p) <= set(doc), set(p) ^ set(doc)
            seen |= set(p)
    assert set(doc) - seen <= UNREACHED


def test_accuracy_is_as_documented(cases):
    doc = documented("Accuracy")
    seen = [data["accuracy"] for data in cases if "accuracy" in data]
    assert seen  # the planar arm compares its tip with measured x, y
    for acc in seen:
        assert set(acc) == set(doc)
        assert set(acc["points"]) <= {"nominal", "least_squares", "certified"}
        assert {"nominal", "least_squares"} <= set(acc["points"])
        for point in acc["points"].values():
            assert set(point) == {"axes", "distance", "distances"}
            assert set(point["axes"]) == set(acc["columns"])
        assert {"max", "median", "unbounded", "axes", "distances", "box_max",
                "box_median"} == set(acc["bound"])
