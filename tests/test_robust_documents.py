"""Faulty documents given back to calibc: a result JSON with a garbled field is one user
error from `calibc report` (exit 2, never an internal error), and an error located in a
long line (a one-line JSON, a wide CSV row) shows a window of it around the caret, not
the whole line."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from cli_run import run
from hypothesis import given, settings
from hypothesis import strategies as st

from calib_dsl.frontend.diagnostics import CalError, Loc

EXAMPLES = Path(__file__).resolve().parents[1] / "models" / "examples"


@pytest.fixture(scope="module")
def result(tmp_path_factory) -> dict:
    d = tmp_path_factory.mktemp("arm")
    for name in ("planar_arm.cal", "planar_arm_robot.cal", "planar_arm.csv"):
        shutil.copy(EXAMPLES / name, d / name)
    res = run("solve", "planar_arm.cal", "--json", "r.json", "-q", cwd=d)
    assert res.exit_code == 0, res.output
    return json.loads((d / "r.json").read_text())


GARBLED = {
    "a result end as text": lambda d: d["parameters"]["l1"].__setitem__("result", ["x", 1]),
    "a result as a number": lambda d: d["parameters"]["l1"].__setitem__("result", 3),
    "a parameter as a list": lambda d: d["parameters"].__setitem__("l1", [1, 2]),
}


@pytest.mark.parametrize("name", sorted(GARBLED))
def test_a_garbled_result_is_one_user_error_from_report(tmp_path, result, name):
    doc = json.loads(json.dumps(result))
    GARBLED[name](doc)
    (tmp_path / "r.json").write_text(json.dumps(doc))
    res = run("report", "r.json", "-o", "r.html", cwd=tmp_path)
    assert res.exit_code == 2, res.output
    assert "internal error" not in res.output and "Traceback" not in res.output
    assert res.output.startswith("error: ") or ": error: " in res.output.splitlines()[0]


def test_the_intact_result_still_makes_its_report(tmp_path, result):
    (tmp_path / "r.json").write_text(json.dumps(result))
    res = run("report", "r.json", "-o", "r.html", cwd=tmp_path)
    assert res.exit_code == 0, res.output
    assert (tmp_path / "r.html").stat().st_size > 0


@settings(max_examples=60, deadline=None)
@given(left=st.integers(0, 400), right=st.integers(0, 400))
def test_a_long_line_is_shown_as_a_window_with_the_caret_under_its_place(left, right):
    import tempfile

    line = "a" * left + "X" + "b" * right
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "f.txt"
        path.write_text("first\n" + line + "\n")
        shown = CalError("bad", Loc(str(path), 2, left + 1)).render().splitlines()
    assert len(shown) == 3
    text, caret = shown[1][4:], shown[2][4:]
    assert len(text) <= 60 * 2 + 2 * 3 + 1  # a window, whatever the line's length
    assert text[len(caret) - 1] == "X"  # the caret stays under the character it names
    if len(line) <= 60:
        assert text == line  # a short line is shown whole
