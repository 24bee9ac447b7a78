"""Held-out files as a user makes them for `calibc validate` / `predict --at`: a file that
lacks a measured column validates the others (never "not covered" for a value it does not
have), and a faulty file is one error before the calibration's time is spent."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from cli_run import run

from calib_dsl import pipeline

EXAMPLES = Path(__file__).resolve().parents[1] / "models" / "examples"


@pytest.fixture
def arm(tmp_path: Path) -> Path:
    for name in ("planar_arm.cal", "planar_arm_robot.cal", "planar_arm.csv"):
        shutil.copy(EXAMPLES / name, tmp_path / name)
    return tmp_path


def _without(src: Path, column: str, out: Path) -> None:
    lines = [ln.split(",") for ln in src.read_text().splitlines()]
    j = lines[0].index(column)
    out.write_text("".join(",".join(c for i, c in enumerate(ln) if i != j) + "\n"
                           for ln in lines))


@pytest.mark.parametrize("column", ["x", "y"])
def test_a_held_out_file_without_a_measured_column_validates_the_others(arm, column):
    held = arm / "held.csv"
    _without(arm / "planar_arm.csv", column, held)
    res = run("validate", "planar_arm.cal", "--at", "held.csv", "--json", "v.json", "-q",
              cwd=arm)
    assert res.exit_code == 0, res.output
    doc = json.loads((arm / "v.json").read_text())
    # the file's rows are the calibration's own: the true positions lie in their boxes
    assert doc["coverage"] == 1.0 and doc["not_covered"] == []
    assert doc["not_measured"] == [column]
    assert all(column not in r["columns"] for r in doc["held_out"])
    assert f"not compared: {column}" in res.output


def test_a_complete_held_out_file_names_no_column_not_compared(arm):
    res = run("validate", "planar_arm.cal", "--at", "planar_arm.csv", "--json", "v.json",
              "-q", cwd=arm)
    assert res.exit_code == 0, res.output
    assert json.loads((arm / "v.json").read_text())["not_measured"] == []
    assert "not compared" not in res.output


def test_a_held_out_row_outside_its_box_is_not_covered(arm):
    """The fix must not hide a real miss: a measured value far off still fails its row."""
    lines = (arm / "planar_arm.csv").read_text().splitlines()
    cells = lines[2].split(",")
    cells[3] = repr(float(cells[3]) + 0.5)
    lines[2] = ",".join(cells)
    (arm / "held.csv").write_text("\n".join(lines) + "\n")
    res = run("validate", "planar_arm.cal", "--at", "held.csv", "--json", "v.json", "-q",
              cwd=arm)
    assert res.exit_code == 0, res.output
    doc = json.loads((arm / "v.json").read_text())
    assert [r["row"] for r in doc["not_covered"]] == [2]


FAULTY_AT = {
    "nan": ("q1,q2,x,y\n0.1,nan,1,1\n", "'nan' is not a finite number"),
    "an input missing": ("q1,x,y\n0.1,1,1\n", "has no column 'q2'"),
    "empty": ("", "is empty"),
    "text": ("q1,q2,x,y\n0.1,abc,1,1\n", "'abc' is not a number"),
}


@pytest.mark.parametrize("command", ["validate", "predict"])
@pytest.mark.parametrize("name", sorted(FAULTY_AT))
def test_a_faulty_held_out_file_fails_before_the_calibration(arm, monkeypatch, command,
                                                             name):
    text, message = FAULTY_AT[name]
    (arm / "held.csv").write_text(text)
    solved = []
    real = pipeline.solve
    monkeypatch.setattr(pipeline, "solve", lambda *a, **k: solved.append(1) or real(*a, **k))
    res = run(command, "planar_arm.cal", "--at", "held.csv", "-q", cwd=arm)
    assert res.exit_code == 2, res.output
    assert message in res.output and "Traceback" not in res.output
    assert solved == []  # the file's fault is found before the solve
