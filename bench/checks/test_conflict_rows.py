"""Test A with one tool coordinate of one row moved by 1-3 cm, five random rows, columns and
sizes of fault: proven inconsistent, and the rows without which the rest is proven
consistent are that row alone, named by file and line. Each case is a solve and a conflict
search (tens of solves of Test A): too heavy for `make test`, where one case runs through the
command (tests/outliers/test_conflict.py)."""

from __future__ import annotations

import numpy as np
import pytest

from calib_dsl.elaborate.elaborator import Inputs
from calib_dsl.pipeline import conflict, load, solve
from tests.outliers.test_conflict import MODEL, faulty

CASES = [(int(r), str(c), float(d)) for r, c, d in zip(
    np.random.default_rng(23).integers(1, 51, 5),
    np.random.default_rng(24).choice(["a1x", "a2y", "a3z", "a1z", "a2x"], 5),
    [0.01, -0.02, 0.03, -0.01, 0.015], strict=True)]


@pytest.mark.parametrize("row, column, delta", CASES)
def test_a_moved_coordinate_is_named(tmp_path, row, column, delta):
    data = faulty(tmp_path, row, column, delta)
    inputs = Inputs(data={"m": data})
    assert solve(load(MODEL, inputs=inputs)).status == "infeasible"
    found = conflict(MODEL, inputs=inputs)
    assert found is not None and found.consistent
    assert [r.row for r in found.rows] == [row]
    assert found.rows[0].line == row + 1 and found.rows[0].file == str(data)
