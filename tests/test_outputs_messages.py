"""The messages of issue 40's item 7: each says where and what, and sends no raw control
character to the terminal."""

from __future__ import annotations

from pathlib import Path

from cli_run import run

from calib_dsl.frontend.diagnostics import visible

ROOT = Path(__file__).resolve().parents[1]
CIRCLE = ROOT / "models" / "examples" / "circle_fit.cal"


def test_include_of_a_directory_says_so(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "m.cal").write_bytes(b'include "sub";\nparam a in [0, 1];\n')
    res = run("compile", tmp_path / "m.cal")
    assert res.exit_code == 2
    assert res.stderr.startswith(f"{tmp_path / 'm.cal'}:1:1: error: include file 'sub' is a "
                                 "directory")


def test_a_latin1_model_gives_its_line(tmp_path):
    (tmp_path / "m.cal").write_bytes(b"param a in [0, 1];\n# caf\xe9\nparam b in [0, 1];\n")
    res = run("compile", tmp_path / "m.cal")
    assert res.exit_code == 2
    assert res.stderr.startswith(f"{tmp_path / 'm.cal'}:2:6: error: model file ")
    assert "not UTF-8 text" in res.stderr and "0xe9" in res.stderr


def test_a_latin1_table_gives_its_line(tmp_path):
    (tmp_path / "d.csv").write_bytes(b"x,y\n1,2\n3,4\n5,\xe96\n")
    res = run("solve", CIRCLE, "--data", tmp_path / "d.csv", "-q")
    assert res.exit_code == 2
    assert res.stderr.startswith(f"{tmp_path / 'd.csv'}:4:3: error: data file ")


def test_nul_bytes_are_escaped(tmp_path):
    (tmp_path / "m.cal").write_bytes(b"param a in [0, 1];\nparam b\x00 in [0, 1];\n")
    (tmp_path / "d.csv").write_bytes(b"x,y\n1,2\n3,4\x00\n")
    for res in (run("compile", tmp_path / "m.cal"),
                run("solve", CIRCLE, "--data", tmp_path / "d.csv", "-q")):
        assert res.exit_code == 2
        assert "\x00" not in res.stderr and "\\x00" in res.stderr
    lines = run("compile", tmp_path / "m.cal").stderr.splitlines()
    assert lines[1].strip() == "param b\\x00 in [0, 1];"
    assert lines[2].index("^") == lines[1].index("\\x00")  # the caret under the escape


def test_visible_keeps_line_breaks_and_text():
    assert visible("a\tb\nc\x1b[31m\x7f") == "a\tb\nc\\x1b[31m\\x7f"


def test_an_inconsistent_circle_names_its_row(tmp_path):
    rows = (ROOT / "models" / "examples" / "circle.csv").read_text(encoding="utf-8")
    lines = rows.splitlines()
    x, y, note = lines[3].split(",")
    lines[3] = f"9.5,{y},{note}"  # data row 3 moved off the circle
    (tmp_path / "bad.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    res = run("solve", CIRCLE, "--data", tmp_path / "bad.csv", "-q")
    assert res.exit_code == 1
    named = res.stdout.split("the worst rows by least squares: ", 1)[1]
    assert named.startswith(f"{tmp_path / 'bad.csv'}:4 (data row 3,")
    assert "--exclude" in named
    rest = run("solve", CIRCLE, "--data", tmp_path / "bad.csv", "-q", "--exclude", "3")
    assert rest.exit_code == 0
