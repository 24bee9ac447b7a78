"""Every CSV calibc writes holds numbers a reader can parse (no `np.float64(...)` reprs), and a
validation never claims a coverage it did not check."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from batch_project import FILES
from click.testing import CliRunner

from calib_dsl import cli

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "models" / "examples"


def run(*args: object):
    return CliRunner().invoke(cli.main, [str(a) for a in args], catch_exceptions=False)


def write_line(tmp: Path) -> Path:
    for name in ("line.cal", "a.csv"):
        (tmp / name).write_text(FILES[name], encoding="utf-8")
    return tmp / "line.cal"


def assert_numeric_cells(text: str, skip_columns: int = 0) -> int:
    """Every cell after the header parses as a float, never NaN (an unbounded end is
    -inf or inf); how many rows there were."""
    lines = text.splitlines()
    assert lines, "an empty CSV"
    for line in lines[1:]:
        for cell in line.split(",")[skip_columns:]:
            assert not math.isnan(float(cell)), f"cell {cell!r} of {line!r}"
    return len(lines) - 1


def test_predict_csv_cells_are_numbers(tmp_path):
    line = write_line(tmp_path)
    res = run("predict", line, "--at", tmp_path / "a.csv", "--at-rows", "1..2",
              "--csv", tmp_path / "p.csv", "-q")
    assert res.exit_code == 0, res.output
    text = (tmp_path / "p.csv").read_text(encoding="utf-8")
    assert text.splitlines()[0] == "row,line,y_lo,y_hi"
    assert assert_numeric_cells(text) == 2


def test_simulate_csv_cells_are_numbers(tmp_path):
    res = run("simulate", EXAMPLES / "planar_arm.cal", "--configs", "5", "-o",
              tmp_path / "s.csv", "-q")
    assert res.exit_code == 0, res.output
    assert assert_numeric_cells((tmp_path / "s.csv").read_text(encoding="utf-8")) == 5


def test_simulate_to_standard_output(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    res = run("simulate", EXAMPLES / "planar_arm.cal", "--configs", "4", "-o", "-", "-q")
    assert res.exit_code == 0, res.output
    assert not (tmp_path / "-").exists()
    assert res.stdout.splitlines()[0] == "q1,q2,x,y"
    assert assert_numeric_cells(res.stdout) == 4
    assert "wrote 4 configurations" in res.stderr


@pytest.mark.parametrize("at", ["x,y\n100,0\n1,5\n"])
def test_validate_without_a_measured_column_is_a_user_error(tmp_path, at):
    (tmp_path / "F.csv").write_text(at, encoding="utf-8")
    res = run("validate", EXAMPLES / "circle_fit.cal", "--at", tmp_path / "F.csv", "-q")
    assert res.exit_code == 2
    assert "coverage" not in res.stdout
    assert res.stderr.startswith("error: the model has no measured column for the held-out")


def test_validate_of_a_file_without_measured_values_is_a_user_error(tmp_path):
    line = write_line(tmp_path)
    (tmp_path / "x.csv").write_text("x\n1\n2\n", encoding="utf-8")
    res = run("validate", line, "--at", tmp_path / "x.csv", "-q", "--json", "-")
    assert res.exit_code == 2 and not res.stdout
    assert "holds no measured value (y)" in res.stderr


def test_predict_without_a_measured_column_says_none(tmp_path):
    (tmp_path / "F.csv").write_text("x,y\n100,0\n", encoding="utf-8")
    res = run("predict", EXAMPLES / "circle_fit.cal", "--at", tmp_path / "F.csv", "-q")
    assert res.exit_code == 0 and "nan" not in res.stdout
    assert "widths: median none, max none" in res.stdout
