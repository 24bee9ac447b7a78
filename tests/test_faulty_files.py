"""Faulty data files through the command line, as a user makes them: each is read correctly
(a legitimate variant of the file) or gives ONE error line, `file:line:col: error: ...` or
`error: ...`, and exit 2; never a traceback. Then random corruptions of a valid file (a cell
or a line deleted, duplicated or garbled), and unit mistakes on a simulated UR10 campaign,
where the message must name the column."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pytest
from cli_run import run
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

ROOT = Path(__file__).resolve().parents[1]
MODEL = """units mm, rad;
const e = 0.1;
param a in [-10, 10] true 2;
param b in [-10, 10] true 1;
table m = "d.csv" { x in mm : +- 0.001; y in mm : +- e; }
for k in 1..rows(m) { a * m.x[k] + b == m.y[k]; }
"""
GOOD = "x,y\n" + "".join(f"{x},{2 * x + 1 + 0.05 * math.sin(x)!r}\n" for x in range(1, 9))
LINES = GOOD.splitlines(keepends=True)

# Variants of GOOD the table reads as GOOD.
READ = {
    "BOM": b"\xef\xbb\xbf" + GOOD.encode(),
    "CRLF line ends": GOOD.replace("\n", "\r\n").encode(),
    "a trailing blank line": (GOOD + "\n").encode(),
    "a row of whitespace": "".join([*LINES[:3], "   \t\n", *LINES[3:]]).encode(),
    "an extra column": "".join(ln.rstrip("\n") + (",z\n" if i == 0 else ",0\n")
                               for i, ln in enumerate(LINES)).encode(),
    "spaces around cells": GOOD.replace(",", " , ").encode(),
    "a quoted header": GOOD.replace("x,y", '"x","y"', 1).encode(),
}
# (file, a part of the message, where: "line:col" in d.csv, or "" for no position)
FAULTY = {
    "empty file": (b"", "is empty", "1:1"),
    "header only": (b"x,y\n", "has a header but no data rows", "2:1"),
    "a missing column": (b"x\n1\n2\n", "has no column 'y'", "1:1"),
    "a duplicated header": (b"x,y,y\n1,3,3\n", "column 'y' appears twice", "1:3"),
    "the header twice": (b"x,y\nx,y\n1,3\n", "'x' is not a number", "2:1"),
    "a row with too few fields": (b"x,y\n1,3\n2\n", "1 fields, but the header has 2", "3:2"),
    "a row with too many fields": (b"x,y\n1,3\n2,5,9\n", "3 fields, but the header has 2",
                                   "3:3"),
    "NaN": (b"x,y\n1,3\n2,nan\n", "'nan' is not a finite number", "3:2"),
    "inf": (b"x,y\n1,3\n2,-inf\n", "'-inf' is not a finite number", "3:2"),
    "an empty cell": (b"x,y\n1,3\n2,\n", "empty cell", "3:2"),
    "a decimal comma": (b'x,y\n1,3\n"2,5",5\n', "'2,5' is not a number", "3:1"),
    "text in a number column": (b"x,y\n1,3\n2,five\n", "'five' is not a number", "3:2"),
    "semicolons": (b"x;y\n1;3\n", 'looks ";"-separated: say separator = ";"', "1:1"),
    "tabs": (b"x\ty\n1\t3\n", 'looks tab-separated: say separator = "tab"', "1:1"),
    "a header in capitals": (b"X,Y\n1,3\n", "the file has 'X' for 'x', 'Y' for 'y': header "
                             "names are case-sensitive", "1:1"),
    "binary": (bytes(range(256)) * 4, "", "1:1"),
    "UTF-16": ("x,y\n1,3\n".encode("utf-16"), "is not UTF-8 text", "1:1"),
}


def _error_lines(output: str) -> list[str]:
    return [ln for ln in output.splitlines() if "error:" in ln]


def _solve(tmp: Path, data: bytes, *options: str):
    (tmp / "m.cal").write_text(MODEL)
    (tmp / "d.csv").write_bytes(data)
    return run("solve", "m.cal", "-q", "--no-identify", "--no-inner", *options, cwd=tmp)


def _one_error(res, where: str, message: str) -> None:
    assert res.exit_code == 2, res.output
    assert "Traceback" not in res.output
    errors = _error_lines(res.output)
    assert len(errors) == 1, res.output
    prefix = f"d.csv:{where}: error: " if where else "error: "
    assert errors[0].startswith(prefix) and message in errors[0], errors[0]


@pytest.mark.parametrize("name", list(READ))
def test_a_legitimate_variant_is_read_as_the_clean_file(tmp_path, name):
    clean = _solve(tmp_path, GOOD.encode(), "--json", "clean.json")
    variant = _solve(tmp_path, READ[name], "--json", "variant.json")
    assert clean.exit_code == variant.exit_code == 0, variant.output
    results = [{n: p["result"] for n, p in json.loads((tmp_path / f).read_text())
                ["parameters"].items()} for f in ("clean.json", "variant.json")]
    assert results[0] == results[1]


@pytest.mark.parametrize("name", list(FAULTY))
def test_a_faulty_file_gives_one_located_error(tmp_path, name):
    data, message, where = FAULTY[name]
    _one_error(_solve(tmp_path, data), where, message)


@pytest.mark.parametrize("args, message", [
    (["--data", "nope.csv"], "data file 'nope.csv' not found"),
    (["--data", "."], "data file '.' is a directory"),
    (["--data", "zz=d.csv"], "a data file was given for table 'zz'"),
    (["-D", "e=abc"], "-D e=abc: the value must be a number"),
    (["-D", "e=1,5"], "-D e=1,5: the value must be a number"),
    (["-D", "e=nan"], "-D e=nan: the value must be a number"),
    (["-D", "e"], "-D e: write NAME=VALUE"),
    (["--rows", "0..3"], "rows are numbered from 1"),
    (["--rows", "5..2"], "the range 5..2 is empty"),
    (["--rows", "1..99"], "reach past the end of the table (8 rows)"),
    (["--rows", "x"], "'x' is not a row range"),
])
def test_bad_options_give_one_error(tmp_path, args, message):
    res = _solve(tmp_path, GOOD.encode(), *args)
    assert res.exit_code == 2 and message in res.output, res.output
    assert len(_error_lines(res.output)) == 1, res.output


@pytest.mark.parametrize("command", [["solve", "."], ["compile", "."], ["identify", "."],
                                     ["validate", ".", "--at", "d.csv", "-q"],
                                     ["predict", "m.cal", "--at", ".", "-q"],
                                     ["plan", ".", "--n", "3", "-o", "p.csv"],
                                     ["export", ".", "--format", "json"],
                                     ["report", ".", "-o", "r.html"]])
def test_a_directory_given_as_a_file_is_one_error_line(tmp_path, command):
    (tmp_path / "m.cal").write_text(MODEL)
    (tmp_path / "d.csv").write_text(GOOD)
    res = run(*command, cwd=tmp_path)
    assert res.exit_code == 2, res.output
    assert res.output.startswith("error: ") and "directory" in res.output, res.output
    assert "Usage:" not in res.output and len(res.output.strip().splitlines()) == 1


def test_a_model_whose_data_file_is_missing(tmp_path):
    (tmp_path / "m.cal").write_text(MODEL.replace('"d.csv"', '"none.csv"'))
    res = run("solve", "m.cal", "-q", cwd=tmp_path)
    assert res.exit_code == 2
    assert _error_lines(res.output)[0].startswith("m.cal:5:11: error: data file ")


# -- random corruption of a valid file ------------------------------------------------------
@st.composite
def corrupted(draw) -> bytes:
    lines = [ln.rstrip("\n").split(",") for ln in LINES]
    for _ in range(draw(st.integers(1, 3))):
        i = draw(st.integers(0, len(lines) - 1))
        op = draw(st.sampled_from(["delete line", "duplicate line", "delete cell",
                                   "duplicate cell", "garble cell"]))
        if op == "delete line" and len(lines) > 1:
            del lines[i]
        elif op == "duplicate line":
            lines.insert(i, list(lines[i]))
        elif lines[i]:
            j = draw(st.integers(0, len(lines[i]) - 1))
            if op == "delete cell":
                del lines[i][j]
            elif op == "duplicate cell":
                lines[i].insert(j, lines[i][j])
            else:
                lines[i][j] = draw(st.text(st.characters(codec="utf-8"), max_size=6))
    return "".join(",".join(ln) + "\n" for ln in lines).encode("utf-8", "surrogatepass")


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(corrupted())
def test_a_corrupted_file_is_a_verdict_or_one_error(tmp_path, data):
    res = _solve(tmp_path, data)
    assert res.exit_code in (0, 1, 2, 4), res.output
    assert "Traceback" not in res.output and "internal error" not in res.output, res.output
    if res.exit_code == 2:
        assert len(_error_lines(res.output)) == 1, res.output


# -- unit mistakes: the column is named ------------------------------------------------------
def _ur10_campaign(tmp: Path, scale: dict[int, float]) -> Path:
    """20 simulated UR10 rows (models/ur10_simulated.cal) with the columns at the indices of
    `scale` multiplied by their factor (a unit mistake), as the tracker's dialect writes it."""
    path = tmp / "u.csv"
    res = run("simulate", ROOT / "models" / "ur10_simulated.cal", "--configs", 20, "--seed", 8,
              "-o", path, "-q")
    assert res.exit_code == 0, res.output
    rows = list(csv.reader(path.open(), delimiter=";"))
    for r in rows[1:]:
        for i, f in scale.items():
            r[i] = repr(float(r[i].replace(",", ".")) * f).replace(".", ",")
    with path.open("w", newline="") as out:
        csv.writer(out, delimiter=";").writerows(rows)
    return path


@pytest.mark.slow
def test_metres_in_a_mm_column_are_named_when_least_squares_fails(tmp_path):
    path = _ur10_campaign(tmp_path, {6: 1e-3, 7: 1e-3, 8: 1e-3})  # x, y, z in m
    res = run("solve", ROOT / "models" / "ur10_simulated.cal", "--data", f"m={path}", "-q",
              cwd=tmp_path)
    assert res.exit_code == 2, res.output
    line, = _error_lines(res.output)
    assert "columns x, y, z: the values spread" in line and "1000 (mm and m)" in line, line


@pytest.mark.slow
def test_degrees_in_a_rad_joint_column_are_named(tmp_path):
    path = _ur10_campaign(tmp_path, {1: 180 / math.pi})  # shoulder_lift_joint in deg
    res = run("solve", ROOT / "models" / "ur10_simulated.cal", "--data", f"m={path}", "-q",
              cwd=tmp_path)
    assert res.exit_code == 1, res.output
    assert "units to check" in res.output
    assert "column q2 (up to" in res.output and "are they degrees?" in res.output, res.output


# -- faulty models: the first error, located, and nothing after it ---------------------------
@pytest.mark.parametrize("source, where, message", [
    ("param a in [0, 1];\nparam b in [0 1];\nparam c in [0, 1;\nvar ;\n", "2:15",
     "unexpected number '1'"),
    ("param a in [0, 1];\na == zz + yy;\n", "2:6", "unknown name 'zz'"),
    ("param a in [1, 0];\nparam b in [2, 1];\n", "1:12", "empty interval"),
    ("robot r(q in [1, 0]) { joint theta = q; }\nparam a in [0, 1];\n", "1:14",
     "empty interval"),
    ("robot r(q in [1, 1]) { joint theta = q; }\nparam a in [0, 1];\n", "1:14",
     "a joint limit is a finite range [lo, hi] with lo < hi"),
])
def test_a_faulty_model_gives_its_first_error_only(tmp_path, source, where, message):
    (tmp_path / "t.cal").write_text(source)
    res = run("solve", "t.cal", "-q", cwd=tmp_path)
    assert res.exit_code == 2, res.output
    line, = _error_lines(res.output)
    assert line.startswith(f"t.cal:{where}: error: ") and message in line, line


# -- the --at file of predict and validate: its own reader, the same standard ---------------
AT_FAULTY = {
    "no input column": (b"y\n5\n6\n", "", "'at.csv' has no column 'x': the configurations need it"),
    "semicolons": (b"x;y\n5;11\n", "", "'at.csv' has no column 'x'"),
    "NaN": (b"x\nnan\n", "2:1", "'nan' is not a finite number"),
    "a duplicated header": (b"x,x\n5,5\n", "1:2", "column 'x' appears twice"),
    "text": (b"x\n\n\nfive\n", "4:1", "'five' is not a number"),
    "not UTF-8": (b"x\n5\n6\xff\n", "3:2", "'at.csv' is not UTF-8 text"),
}


@pytest.mark.parametrize("command", ["predict", "validate"])
@pytest.mark.parametrize("name", list(AT_FAULTY))
def test_a_faulty_at_file_is_one_error_about_it(tmp_path, command, name):
    data, where, message = AT_FAULTY[name]
    (tmp_path / "m.cal").write_text(MODEL)
    (tmp_path / "d.csv").write_text(GOOD)
    (tmp_path / "at.csv").write_bytes(data)
    res = run(command, "m.cal", "--at", "at.csv", "-q", cwd=tmp_path)
    assert res.exit_code == 2, res.output
    line, = _error_lines(res.output)
    assert line.startswith(f"at.csv:{where}: error: " if where else "error: "), line
    assert message in line and "calibc-predict" not in line, line


@pytest.mark.slow
@pytest.mark.parametrize("command", ["predict", "validate"])
def test_configurations_beyond_the_joint_limits_are_named(tmp_path, command):
    """(a joint column in degrees read as radians was predicted at without a word)"""
    model = ROOT / "models" / "ur10_simulated.cal"
    res = run("simulate", model, "--configs", "30", "--seed", "3", "-o", tmp_path / "d.csv",
              "-q")
    assert res.exit_code == 0, res.output
    lines = (tmp_path / "d.csv").read_text(encoding="utf-8").splitlines()
    cells = lines[2].split(";")
    cells[2] = "100,5"  # rad: beyond the UR10's +- 2 pi
    at = tmp_path / "at.csv"
    at.write_text("\n".join([lines[0], lines[1], ";".join(cells), lines[3]]) + "\n",
                  encoding="utf-8")
    res = run(command, model, "--data", f"m={tmp_path / 'd.csv'}", "--at", at, "-q")
    assert res.exit_code in (0, 1), res.output
    warned = [ln for ln in res.output.splitlines() if "calibc: warning: " in ln]
    assert len(warned) == 1 and "m.q3 lies outside the joint's limits" in warned[0] \
        and f"{at}:3 (data row 2) 100.5" in warned[0], res.output


def test_a_quoted_at_header_is_read(tmp_path):
    (tmp_path / "m.cal").write_text(MODEL)
    (tmp_path / "d.csv").write_text(GOOD)
    (tmp_path / "at.csv").write_text('"x","y"\n5,11\n')
    res = run("validate", "m.cal", "--at", "at.csv", "-q", cwd=tmp_path)
    assert res.exit_code == 0 and "coverage 1.0000" in res.output, res.output


@pytest.mark.parametrize("args, message", [
    (["solve", "m.cal", "--tol", "-1"], "Invalid value for '--tol'"),
    (["solve", "m.cal", "--max-sweeps", "0"], "Invalid value for '--max-sweeps'"),
    (["solve", "m.cal", "--outliers", "-1"], "Invalid value for '--outliers'"),
    (["solve", "m.cal", "--json", "."], "Invalid value for '--json'"),
    (["solve"], "Missing argument 'MODEL'"),
    (["simulate", "m.cal", "--configs", "0", "-o", "s.csv"], "Invalid value for '--configs'"),
    (["simulate", "m.cal", "--configs", "5", "--seed", "-1", "-o", "s.csv"], "'--seed'"),
    (["predict", "m.cal", "--at", "d.csv", "--csv", "."], "Invalid value for '--csv'"),
    (["plan", "m.cal", "--n", "3"], "Missing option '-o'"),
    (["report", "r.json", "--validation", ".", "-o", "r.html"], "'--validation'"),
    (["export", "r.json", "--format", "xml"], "Invalid value for '--format'"),
    (["solve", "m.cal", "--no-such-option"], "No such option"),
    (["no-such-command"], "No such command"),
])
def test_a_bad_option_is_one_error_line(tmp_path, args, message):
    """click's usage errors are three lines (usage, a hint, 'Error: ...'): one line here,
    `error: ...` as every other user error, still exit 2."""
    (tmp_path / "m.cal").write_text(MODEL)
    (tmp_path / "d.csv").write_text(GOOD)
    res = run(*args, cwd=tmp_path)
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], lines
    assert "--help" in lines[0]  # (where the usage is)


def test_no_command_still_prints_the_help():
    res = run()
    assert "Commands:" in res.output and "error:" not in res.output


def test_identify_counts_measured_values_not_rows():
    """(it said '10 rows' of the planar arm's 5-row table, two measured values a row: a user
    checking that the whole file was read would think it read twice)"""
    res = run("identify", ROOT / "models" / "examples" / "planar_arm.cal")
    assert res.exit_code == 0 and "(10 measured values)" in res.output, res.output
