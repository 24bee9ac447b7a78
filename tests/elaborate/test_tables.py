"""CSV measurement tables: reading, outward cell bounds, and every malformed-file error with
its location in the CSV (line, field number)."""

from __future__ import annotations

import tempfile
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from calib_dsl.elaborate.tables import cell_bounds, read_csv
from calib_dsl.frontend.diagnostics import CalError, Loc

DECL = Loc("model.cal", 7, 11)


def write(tmp_path, text: str, name: str = "d.csv") -> str:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return str(p)


def test_reads_declared_columns_in_any_order(tmp_path):
    path = write(tmp_path, "a,b,note,c\n1,2,hello,3\n4.5,-1e-3,x,6\n")
    data = read_csv(path, ["c", "a"])
    assert data.rows == 2 and data.path == path
    assert set(data.columns) == {"c", "a"}  # b and note ignored, note is not numeric
    assert data.columns["a"].tolist() == [1.0, 4.5]
    assert data.columns["c"].tolist() == [3.0, 6.0]
    assert data.lines == [2, 3]


def test_whitespace_blank_lines_bom_and_crlf(tmp_path):
    p = tmp_path / "d.csv"
    p.write_bytes("\ufeff x , y \r\n\r\n 1 ,2\r\n\r\n3, +4 \r\n\r\n".encode())
    data = read_csv(str(p), ["x", "y"])
    assert data.rows == 2
    assert data.columns["y"].tolist() == [2.0, 4.0]
    assert data.lines == [3, 5]


@pytest.mark.parametrize(("text", "message", "line", "col"), [
    ("", "is empty", 1, 1),
    ("\n\n", "is empty", 1, 1),
    ("a,b\n", "has a header but no data rows", 2, 1),
    ("a,b\n1,2\n3\n", "row 2: 1 fields, but the header has 2", 3, 2),
    ("a,b\n1,2,3\n", "row 1: 3 fields, but the header has 2", 2, 3),
    ("a,b\n1,x\n", "row 1, column 'b': 'x' is not a number", 2, 2),
    ("a,b\n1,2\n1,\n", "row 2, column 'b': empty cell", 3, 2),
    ("a,b\nnan,2\n", "row 1, column 'a': 'nan' is not a finite number", 2, 1),
    ("a,b\n1,-inf\n", "column 'b': '-inf' is not a finite number", 2, 2),
    ("a,b\n1,Infinity\n", "'Infinity' is not a finite number", 2, 2),
    ("a,b\n1,1e999\n", "'1e999' is too large for a float", 2, 2),
    ("a,b\n1,1_0\n", "'1_0' is not a number", 2, 2),
    ("a,c\n1,2\n", "has no column 'b' (its columns: a, c)", 1, 1),
    ("x,a,b,a\n0,1,2,3\n", "column 'a' appears twice in the header (fields 2 and 4)", 1, 4),
])
def test_malformed_csv_is_located_in_the_csv(tmp_path, text, message, line, col):
    path = write(tmp_path, text)
    with pytest.raises(CalError) as err:
        read_csv(path, ["a", "b"], DECL)
    assert message in err.value.message
    assert path in err.value.message  # the message names the file
    assert err.value.loc == Loc(path, line, col)


def test_missing_file_is_located_at_the_declaration(tmp_path):
    path = str(tmp_path / "nope.csv")
    with pytest.raises(CalError, match="data file '.*nope.csv' not found") as err:
        read_csv(path, ["a"], DECL)
    assert err.value.loc == DECL


def test_directory_or_binary_file(tmp_path):
    with pytest.raises(CalError, match="is a directory"):
        read_csv(str(tmp_path), ["a"], DECL)
    p = tmp_path / "bin.csv"
    p.write_bytes(b"a\n\xff\xfe\n")
    with pytest.raises(CalError, match="not UTF-8"):
        read_csv(str(p), ["a"], DECL)


def test_extra_columns_may_hold_anything(tmp_path):
    path = write(tmp_path, "a,comment\n1,\n2,nan\n3,\"quoted, with comma\"\n")
    assert read_csv(path, ["a"]).columns["a"].tolist() == [1.0, 2.0, 3.0]


def test_cell_error_in_a_row_after_good_rows(tmp_path):
    rows = "\n".join(f"{k},{k}" for k in range(1, 30))
    path = write(tmp_path, "a,b\n" + rows + "\n30,oops\n")
    with pytest.raises(CalError, match="row 30, column 'b'") as err:
        read_csv(path, ["a", "b"])
    assert err.value.loc == Loc(path, 31, 2)


# -- cell bounds: the exact value +- tol, rounded outward ----------------------------------
decimals = st.builds(
    lambda sign, digits, exp: f"{sign}{digits}e{exp}",
    st.sampled_from(["", "-", "+"]), st.integers(0, 10**17), st.integers(-30, 30))
tolerances = st.sampled_from(["0", "1e-5", "1e-4", "0.3", "1e-300", "2.5"])


def upper(tol: str) -> float:
    """The caller's tolerance: the upper float enclosure of the decimal."""
    t = float(tol)
    return t if Fraction(t) >= Fraction(tol) else float(np.nextafter(t, np.inf))


@given(texts=st.lists(decimals, min_size=1, max_size=20), tol=tolerances)
def test_cell_bounds_hold_the_exact_interval(texts, tol):
    with tempfile.TemporaryDirectory() as tmp:
        path = write(Path(tmp), "v\n" + "\n".join(texts) + "\n")
        data = read_csv(path, ["v"])
    lo, hi = cell_bounds(*data.enclosures["v"], upper(tol))
    for text, a, b in zip(texts, lo.tolist(), hi.tolist(), strict=True):
        exact = Fraction(text)
        assert Fraction(a) <= exact - Fraction(tol)
        assert Fraction(b) >= exact + Fraction(tol)
        # and tight: within a few float steps of the exact bounds
        steps = 4 * np.spacing(abs(float(exact)) + float(tol))
        assert Fraction(a) >= exact - Fraction(tol) - Fraction(float(steps))
        assert Fraction(b) <= exact + Fraction(tol) + Fraction(float(steps))


def test_enclosures_are_points_for_floats(tmp_path):
    path = write(tmp_path, "v\n1\n-2.5\n0.1\n1e-1\n")
    data = read_csv(path, ["v"])
    lo, hi = data.enclosures["v"]
    assert lo[:2].tolist() == hi[:2].tolist() == [1.0, -2.5]  # exact floats
    assert lo[2] < 0.1 <= hi[2] or lo[2] <= 0.1 < hi[2]  # 1/10 is not a float
    assert hi[2] == np.nextafter(lo[2], np.inf) and (lo[3], hi[3]) == (lo[2], hi[2])
    assert data.columns["v"].tolist() == [1.0, -2.5, 0.1, 0.1]


def test_cell_bounds_exact_when_possible():
    lo, hi = cell_bounds(np.array([1.0, 0.5]), np.array([1.0, 0.5]), 0.0)
    assert lo.tolist() == hi.tolist() == [1.0, 0.5]
    lo, hi = cell_bounds(np.array([1.0]), np.array([1.0]), 0.25)
    assert (lo[0], hi[0]) == (0.75, 1.25)
    lo, hi = cell_bounds(np.array([1.0]), np.array([1.0]), 1e-4)  # 1 +- 1e-4 is not exact
    low, high = 1 - Fraction(1e-4), 1 + Fraction(1e-4)
    assert Fraction(lo[0]) < low < Fraction(np.nextafter(lo[0], 2))  # rounded down, tightly
    assert Fraction(np.nextafter(hi[0], 0)) < high < Fraction(hi[0])


def test_cell_bounds_are_vectorized_over_a_column(tmp_path):
    path = write(tmp_path, "q\n" + "\n".join(str(k / 7) for k in range(1000)) + "\n")
    data = read_csv(path, ["q"])
    lo, hi = cell_bounds(*data.enclosures["q"], 1e-5)
    assert lo.shape == hi.shape == (1000,)
    assert np.all(lo < data.columns["q"]) and np.all(data.columns["q"] < hi)
