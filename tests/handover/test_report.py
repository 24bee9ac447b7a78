"""The handover report (`calibc report`, `solve --report`): one self-contained HTML file whose
every number is the JSON's, printed outward (guaranteed), inward (certified) or as midpoint
+- half-width, with the verdict, the accuracy, the data's SHA-256 and the command that made it.
Read back with the standard library's HTML parser (tests/handover/page.py)."""

from __future__ import annotations

import hashlib
import json
import math
import re
import shutil
from decimal import Decimal
from pathlib import Path

import pytest

from tests.cli_run import run
from tests.handover.page import intervals, read

ROOT = Path(__file__).resolve().parents[2]
ARM = ROOT / "models" / "examples" / "planar_arm.cal"


@pytest.fixture(scope="module")
def solved(tmp_path_factory) -> tuple[dict, str]:
    """The planar arm solved with --report: its JSON and its report."""
    tmp = tmp_path_factory.mktemp("report")
    res = run("solve", ARM.relative_to(ROOT), "--json", tmp / "r.json", "--report",
              tmp / "r.html", cwd=ROOT)
    assert res.exit_code == 0, res.output
    assert f"wrote the report to {tmp / 'r.html'}" in res.stderr
    return json.loads((tmp / "r.json").read_text()), (tmp / "r.html").read_text()


def number(v) -> Decimal:
    return Decimal(repr(float({"-oo": "-inf", "+oo": "inf"}.get(v, v))))


def test_one_row_per_unknown_every_interval_the_json_s(solved):
    result, html = solved
    page = read(html)
    assert list(page.rows) == list(result["parameters"])
    for name, p in result["parameters"].items():
        shown = intervals(page, name)
        assert set(shown) == {"domain", "result", "inner"}
        for key in ("domain", "result"):  # printed outward: the printed interval holds it
            value, lo, hi = shown[key]
            assert value == p[key]
            assert Decimal(lo) <= number(p[key][0]) and Decimal(hi) >= number(p[key][1])
        value, lo, hi = shown["inner"]  # printed inward: every printed value is certified
        assert value == p["inner"]
        assert number(p["inner"][0]) <= Decimal(lo) <= Decimal(hi) <= number(p["inner"][1])


def test_the_verdict_and_where_it_came_from(solved):
    result, html = solved
    page = read(html)
    (verdict,) = [c for c in page.values if c.json == result["verdict"]]
    assert verdict.text == result["verdict"] == "consistent"
    for f in ("planar_arm.cal", "planar_arm_robot.cal", "planar_arm.csv"):
        digest = hashlib.sha256((ARM.parent / f).read_bytes()).hexdigest()
        assert digest in html
    assert "calibc solve models/examples/planar_arm.cal --json" in html
    assert result["provenance"]["data"][0]["rows"] == 5
    assert "Rows used: <span class=\"num\" data-json=\"5\">5</span>" in html


def test_nothing_is_fetched_and_no_text_becomes_markup(solved, tmp_path):
    result, html = solved
    tags = read(html).tags
    assert not [t for t, _ in tags if t in ("script", "link", "img", "iframe", "object")]
    for _, attrs in tags:  # only in-page references (#id) and SVG namespaces
        for key in ("src", "href", "xlink:href"):
            assert not attrs.get(key) or attrs[key].startswith("#"), attrs
    assert "@import" not in html and not re.search(r"url\((?!#)", html)
    hostile = {**result, "model": "<script>alert(1)</script>"}
    (tmp_path / "h.json").write_text(json.dumps(hostile))
    assert run("report", tmp_path / "h.json", "-o", tmp_path / "h.html").exit_code == 0
    out = (tmp_path / "h.html").read_text()
    assert "<script>" not in out and "&lt;script&gt;alert(1)" in out


def test_report_of_a_written_result_with_its_validation(solved, tmp_path):
    result, _ = solved
    (tmp_path / "r.json").write_text(json.dumps(result))
    held = tmp_path / "held.csv"
    assert run("simulate", ARM, "--configs", 12, "--seed", 5, "-o", held).exit_code == 0
    res = run("validate", ARM, "--at", held, "--json", tmp_path / "v.json")
    assert res.exit_code == 0, res.output
    validation = json.loads((tmp_path / "v.json").read_text())
    res = run("report", tmp_path / "r.json", "--validation", tmp_path / "v.json",
              "-o", tmp_path / "r.html")
    assert res.exit_code == 0 and "wrote the report" in res.output
    page = read((tmp_path / "r.html").read_text())
    shown = {c.json: c.text for c in page.values if isinstance(c.json, float)}
    assert float(shown[validation["coverage"]]) == pytest.approx(validation["coverage"],
                                                                 rel=1e-3)
    for key in ("median", "max"):
        w = validation["width"][key]
        assert math.isclose(float(shown[w]), w, rel_tol=1e-3)


@pytest.mark.parametrize("text, message", [
    (None, "cannot read"),
    ("{\n  \"parameters\": {},\n  oops", ":3:3: error: not JSON"),
    ("[1, 2]", "is not a solve's result's JSON"),
    ('{"parameters": {}, "verdict": NaN}', "not strict JSON: NaN"),
])
def test_user_errors(tmp_path, text, message):
    path = tmp_path / "r.json"
    if text is not None:
        path.write_text(text)
    res = run("report", path, "-o", tmp_path / "r.html")
    assert res.exit_code == 2 and message in res.output
    assert "Traceback" not in res.output and not (tmp_path / "r.html").exists()


def test_an_inconsistent_result_reports_its_verdict(tmp_path):
    for f in ("planar_arm.cal", "planar_arm_robot.cal"):
        shutil.copy(ARM.parent / f, tmp_path)
    lines = (ARM.parent / "planar_arm.csv").read_text().splitlines()
    cells = lines[3].split(",")
    cells[2] = repr(float(cells[2]) + 0.01)  # 100 times the error bound
    (tmp_path / "planar_arm.csv").write_text("\n".join([*lines[:3], ",".join(cells),
                                                        *lines[4:]]) + "\n")
    res = run("solve", tmp_path / "planar_arm.cal", "--json", tmp_path / "r.json",
              "--report", tmp_path / "r.html")
    result = json.loads((tmp_path / "r.json").read_text())
    assert res.exit_code == 1 and result["verdict"] == "inconsistent"
    html = (tmp_path / "r.html").read_text()
    assert re.search(r'data-json="inconsistent">inconsistent<', html)
    assert "no parameter vector within the search domains" in html


def test_the_solve_s_accuracy_statement_comes_first(solved, tmp_path):
    """With the solve's `accuracy` (docs/json.md), the report states the distances before and
    after calibration and the guaranteed bound, each number the JSON's."""
    result, _ = solved
    stats = {"mean": 0.41, "rms": 0.45, "p95": 0.8, "max": 1.5}
    accuracy = {"unit": "m", "columns": ["x", "y"], "distance_columns": ["x", "y"],
                "configurations": 5,
                "points": {"nominal": {"distance": {k: 3 * v for k, v in stats.items()}},
                           "least_squares": {"distance": stats}},
                "bound": {"median": 1.7, "max": 2.1144}}
    (tmp_path / "r.json").write_text(json.dumps({**result, "accuracy": accuracy}))
    assert run("report", tmp_path / "r.json", "-o", tmp_path / "r.html").exit_code == 0
    html = (tmp_path / "r.html").read_text()
    page = read(html)
    shown = {c.json: c.text for c in page.values if isinstance(c.json, float)}
    for v in [*stats.values(), *(3 * v for v in stats.values()), 1.7, 2.1144]:
        assert float(shown[v]) == pytest.approx(v, rel=1e-3)
    assert "before calibration (nominal)" in html and "the certified point" not in html
    assert "guaranteed, every consistent parameter vector" in html


def test_the_min_error_bracket_and_the_combinations_are_the_json_s(solved, tmp_path):
    result, _ = solved
    (tmp_path / "r.json").write_text(json.dumps(result))
    res = run("solve", ARM, "--min-error", "e", "--json", tmp_path / "m.json")
    assert res.exit_code == 0, res.output
    bracket = json.loads((tmp_path / "m.json").read_text())["min_error"]["bracket"]
    res = run("report", tmp_path / "r.json", "--min-error", tmp_path / "m.json",
              "-o", tmp_path / "r.html")
    assert res.exit_code == 0, res.output
    (shown,) = [c for c in read((tmp_path / "r.html").read_text()).values
                if c.key == "bracket"]
    assert shown.json == bracket
    lo, hi = shown.text.strip("[]").split(", ")
    assert bracket[0] is None and lo == "0"  # (exact data: nothing below proven inconsistent)
    assert Decimal(hi) >= number(bracket[1])
