"""A result JSON damaged after the solve wrote it (an end NaN, ends in the wrong order, an
end that is not a number): every export refuses it as one user error, exit 2, rather than
write a box no solve proved or fail with an internal error."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from cli_run import run

ROOT = Path(__file__).resolve().parents[1]
ARM = ROOT / "models" / "examples" / "planar_arm.cal"
FORMATS = ("cal", "dh-table", "json", "urdf", "cell")


@pytest.fixture(scope="module")
def solved(tmp_path_factory) -> tuple[Path, dict]:
    tmp = tmp_path_factory.mktemp("damaged")
    res = run("solve", ARM, "-D", "e=0.01", "--json", tmp / "ok.json", "-q")
    assert res.exit_code == 0, res.output
    return tmp, json.loads((tmp / "ok.json").read_text())


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("ends", [[math.nan, 1.0], [2.0, 1.0], ["abc", 1.0], [1.0]])
def test_a_damaged_result_is_refused_by_every_export(solved, fmt, ends):
    tmp, doc = solved
    name = next(iter(doc["parameters"]))
    doc["parameters"][name]["result"] = ends
    path = tmp / "damaged.json"
    path.write_text(json.dumps(doc))
    res = run("export", "--format", fmt, path)
    assert res.exit_code == 2
    assert res.output.startswith("error: the result's parameters are malformed")


@pytest.mark.parametrize("fmt", FORMATS)
def test_an_unbounded_result_is_still_exported(solved, fmt):
    """"-oo"/"+oo" are how the JSON writes an unbounded end: not damage."""
    tmp, doc = solved
    name = next(iter(doc["parameters"]))
    doc["parameters"][name]["result"] = ["-oo", "+oo"]
    path = tmp / "unbounded.json"
    path.write_text(json.dumps(doc))
    res = run("export", "--format", fmt, path)
    assert res.exit_code == 0, res.output
