"""Leverage: the share of a data row in a parameter's estimate, checked against the closed
form of a straight-line fit, and the warning that names the row that carries a parameter."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from calib_dsl.analysis.leverage import heavy_rows
from calib_dsl.cli import main
from calib_dsl.pipeline import load
from calib_dsl.settings_analysis import FitSettings

LINE = """param a in [-10, 10]; param b in [-10, 10];
table m = "w.csv" { x : +- 1e-9; v : +- 0.01; }
for k in 1..rows(m) { a * m.x[k] + b == m.v[k]; }
"""


def _write(tmp, xs):
    rows = "\n".join(f"{x!r},{0.5 * x + 0.1!r}" for x in xs)
    (tmp / "w.csv").write_text("x,v\n" + rows + "\n")
    (tmp / "line.cal").write_text(LINE)
    return tmp / "line.cal"


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(-3, 3), min_size=4, max_size=9, unique=True), st.floats(-60, 60))
def test_the_slopes_shares_are_the_closed_form(tmp_path_factory, xs, far):
    """For a line fit with equal bounds, row i's share in the slope's estimate is
    (x_i - mean)^2 / sum (x_j - mean)^2; a row above FitSettings' leverage_share is reported,
    with that share."""
    xs = [*xs, far]
    prog = load(_write(tmp_path_factory.mktemp("lev"), xs))
    found = {h.parameter: h for h in heavy_rows(prog, prog.slots.lo, prog.slots.hi, FitSettings())}
    x = np.array(xs)
    if np.ptp(x) < 1e-3:
        return
    share = (x - x.mean()) ** 2 / np.sum((x - x.mean()) ** 2)
    top = int(np.argmax(share))
    if share[top] > FitSettings().leverage_share + 1e-6:
        assert found["a"].share == pytest.approx(share[top], rel=1e-6)
        assert prog.slots.row_keys[found["a"].data_row][1] == top + 1
    elif share[top] < FitSettings().leverage_share - 1e-6:
        assert "a" not in found


def test_the_warning_names_the_far_row(tmp_path):
    model = _write(tmp_path, [0.0, 0.1, 0.2, 0.1, 10.0])
    res = CliRunner().invoke(main, ["solve", str(model), "--no-inner"])
    assert res.exit_code == 0, res.output
    assert "one data row carries most of what the data say about 1 parameter" in res.stderr
    assert "a 80% on" in res.stderr and "w.csv:6 (data row 5)" in res.stderr


def test_no_warning_when_the_rows_share_it(tmp_path):
    model = _write(tmp_path, [-2.0, -1.0, 0.0, 1.0, 2.0])
    res = CliRunner().invoke(main, ["solve", str(model), "--no-inner"])
    assert res.exit_code == 0 and "carries most" not in res.stderr
