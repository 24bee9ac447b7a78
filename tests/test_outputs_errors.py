"""Faults outside calibc's own logic are translated, never an internal error (exit 3): a full
disk, scipy refusing a fixed parameter, a CSV cell of thousands of digits, numbers whose
squares overflow the floats; and numpy's warnings stay off standard error."""

from __future__ import annotations

import math
import subprocess
import sys
import time
from fractions import Fraction
from pathlib import Path

import pytest
from cli_run import run
from hypothesis import given
from hypothesis import strategies as st

from calib_dsl.elaborate.tables import Dialect, _cell, read_csv

ROOT = Path(__file__).resolve().parents[1]
CIRCLE = ROOT / "models" / "examples" / "circle_fit.cal"

# a parameter known to +- k: -D k=0 makes its domain a point
FIXED = """const k = 1e-3;
param a in 1 +- k;
param b in [0, 2] true 1;
table m = "d.csv" { x : +- 0; y : +- 0.01; }
for i in 1..rows(m) { m.y[i] == a * m.x[i] + b; }
"""
LINE_DATA = "x,y\n0,1\n1,2\n2,3.005\n"


def shell(calibc: list[str], *args: object, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([*calibc, *map(str, args)], capture_output=True, text=True,
                          timeout=120, **kw)


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full on this system")
@pytest.mark.parametrize("args", [("solve", CIRCLE, "-q"), ("solve", CIRCLE, "-q", "--json", "-"),
                                  ("compile", CIRCLE)])
def test_a_full_disk_is_a_one_line_error(calibc, args):
    with open("/dev/full", "w") as full:
        res = subprocess.run([*calibc, *map(str, args)], stdout=full, stderr=subprocess.PIPE,
                             text=True, timeout=120)
    assert res.returncode == 2, res.stderr
    assert res.stderr.startswith("error: ") and "No space left on device" in res.stderr
    assert "Traceback" not in res.stderr and len(res.stderr.strip().splitlines()) == 1


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full on this system")
def test_a_full_disk_named_as_the_json_file(calibc):
    res = shell(calibc, "solve", CIRCLE, "-q", "--json", "/dev/full")
    assert res.returncode == 2 and "error: cannot write '/dev/full'" in res.stderr


@pytest.mark.parametrize("command", [("solve", "--lsq", "-q"), ("identify",)])
def test_a_parameter_fixed_by_a_zero_bound(tmp_path, command):
    (tmp_path / "d.csv").write_text(LINE_DATA, encoding="utf-8")
    (tmp_path / "m.cal").write_text(FIXED, encoding="utf-8")
    res = run(command[0], tmp_path / "m.cal", "-D", "k=0", *command[1:])
    assert res.exit_code == 0, res.output
    if command[0] == "solve":
        assert "least-squares estimate inside the guaranteed enclosure: yes" in res.stdout


def _long(digits: str) -> str:
    return "0." + digits


@given(st.text("0123456789", min_size=400, max_size=3000).map(_long)
       | st.integers(401, 10**9).map(lambda e: f"1.5e-{e}")
       | st.integers(0, 2000).map(lambda n: "123456789." + "7" * n + "e-300"))
def test_long_cells_are_enclosed(text):
    """A cell of more digits (or a larger exponent) than is cheap exactly: its enclosure
    still holds its exact value."""
    value, lo, hi = _cell(text, "d.csv", 2, 1, "'x'", 1, Dialect())
    assert lo <= value <= hi
    mantissa, _, exponent = text.partition("e")
    if int(exponent or 0) < -1000:  # exactly, 10**e is too costly to build: below the floats
        assert lo < 0 < hi or 0 < lo
        return
    old = sys.get_int_max_str_digits()
    sys.set_int_max_str_digits(0)
    try:
        exact = Fraction(text)
    finally:
        sys.set_int_max_str_digits(old)
    assert Fraction(lo) <= exact <= Fraction(hi)


def test_a_cell_of_five_thousand_digits(tmp_path):
    tiny = "0." + "0" * 5000 + "1"
    (tmp_path / "d.csv").write_text(f"x,y\n{tiny},2\n1,5\n-2,3\n", encoding="utf-8")
    data = read_csv(tmp_path / "d.csv", ["x", "y"])
    lo, hi = data.enclosures["x"]
    assert lo[0] < 0 < hi[0] and data.columns["x"][0] == 0.0
    res = run("solve", CIRCLE, "--data", tmp_path / "d.csv", "-q", "--no-identify")
    assert res.exit_code in (0, 1), res.output


def test_a_huge_exponent_is_quick(tmp_path):
    (tmp_path / "d.csv").write_text("x,y\n1e-999999999,2\n", encoding="utf-8")
    start = time.perf_counter()
    data = read_csv(tmp_path / "d.csv", ["x", "y"])
    assert time.perf_counter() - start < 5
    assert data.enclosures["x"][0][0] < 0 < data.enclosures["x"][1][0]


def _circle_near_1e154(tmp: Path) -> tuple[Path, Path]:
    rows = [f"{1e154 * (1 + 3 * math.cos(1.1 * k))!r},{1e154 * (2 + 3 * math.sin(1.1 * k))!r}"
            for k in range(6)]
    (tmp / "h.csv").write_text("x,y\n" + "\n".join(rows) + "\n", encoding="utf-8")
    text = CIRCLE.read_text(encoding="utf-8").replace("[-10, 10]", "[-1e155, 1e155]")
    text = text.replace("[0, 10]", "[0, 1e155]")
    for t in "123":
        text = text.replace(f"true {t};", f"true {t}e154;")
    (tmp / "h.cal").write_text(text, encoding="utf-8")
    return tmp / "h.cal", tmp / "h.csv"


@pytest.mark.slow
def test_coordinates_near_1e154(calibc, tmp_path):
    model, data = _circle_near_1e154(tmp_path)
    ident = shell(calibc, "identify", model, "--data", data)
    assert ident.returncode == 2, ident.stderr
    assert ident.stderr.startswith("error: identifiability: the Jacobian") and \
        "not finite" in ident.stderr
    solved = shell(calibc, "solve", model, "--data", data, "-q", "--lsq")
    assert solved.returncode in (0, 1, 4), solved.stderr  # a verdict, whichever
    for res in (ident, solved):
        assert "Warning" not in res.stderr and "Traceback" not in res.stderr, res.stderr


@pytest.mark.parametrize("model", ["unbounded", "language_tour"])
def test_identify_over_unbounded_domains_still_answers(tmp_path, model):
    """Rows infinite at the middle of an unbounded domain are no overflow: no error."""
    path = ROOT / "models" / "examples" / "language_tour.cal"
    if model == "unbounded":
        path = tmp_path / "u.cal"
        path.write_text("param a in [-oo, oo];\nparam b in [0, 1];\na >= b;\n", encoding="utf-8")
    res = run("identify", path)
    assert res.exit_code == 0 and res.stdout.startswith("identifiability at "), res.output


def test_a_1e308_cell_leaks_no_numpy_warning(calibc, tmp_path):
    (tmp_path / "d.csv").write_text("x,y\n1e308,1e308\n1,5\n-2,3\n", encoding="utf-8")
    res = shell(calibc, "solve", CIRCLE, "--data", tmp_path / "d.csv", "-q", "--lsq")
    assert res.returncode in (0, 1)
    assert "RuntimeWarning" not in res.stderr, res.stderr
