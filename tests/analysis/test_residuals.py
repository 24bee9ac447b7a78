"""Residual ranges over a box: each holds measured minus predicted for every parameter vector
of the box and every reading within its bound; checked on the planar arm against its forward
kinematics written out by hand (x = l1 cos q1 + l2 cos(q1 + q2), y likewise)."""

from __future__ import annotations

import numpy as np
import pytest
from planar_arm import simulated_arm, tip

from calib_dsl.analysis.residuals import residual_ranges
from calib_dsl.pipeline import load, solve

Q_ERR, XY_ERR = 1e-6, 1e-4  # planar_arm.cal's bounds


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    """The planar arm solved on 12 simulated noisy rows: program, box, the rows read."""
    tmp = tmp_path_factory.mktemp("arm")
    rows = simulated_arm(tmp, 12, 7)
    prog = load(tmp / "planar_arm.cal")
    sol = solve(prog)
    box = {n: (float(sol.lo[k]), float(sol.hi[k]))
           for n, k in zip(prog.slots.declared_names, prog.slots.declared, strict=True)}
    return prog, box, rows


def test_ranges_hold_every_residual_of_the_box(arm):
    prog, box, rows = arm
    r = residual_ranges(prog, box)
    assert sorted(set(r.columns)) == ["x", "y"] and sorted(set(r.rows)) == list(range(1, 13))
    np.testing.assert_allclose(r.bound, XY_ERR, rtol=1e-9)
    rng = np.random.default_rng(1)
    n = 300
    l1 = rng.uniform(*box["l1"], n)
    l2 = rng.uniform(*box["l2"], n)
    for i, (k, col) in enumerate(zip(r.rows, r.columns, strict=True)):
        row = rows[k - 1]
        q1 = row["q1"] + rng.uniform(-Q_ERR, Q_ERR, n)
        q2 = row["q2"] + rng.uniform(-Q_ERR, Q_ERR, n)
        predicted = tip(l1, l2, q1, q2)[0 if col == "x" else 1]
        residual = row[col] - predicted
        assert np.all(residual >= r.lo[i]) and np.all(residual <= r.hi[i]), (k, col)
        truth = row[col] - tip(1.0, 0.5, row["q1"], row["q2"])[0 if col == "x" else 1]
        assert r.lo[i] <= truth <= r.hi[i]
    assert not r.outside().any()  # the data are consistent: no outlier
    assert np.median(r.hi - r.lo) < 10 * XY_ERR  # an enclosure, not everything


def test_a_box_that_misses_the_data_makes_outliers(arm):
    """Over a box 1 cm off in l2, every tool point is predicted 1 cm too far along the last
    link (0.7 cm or more in x or in y): every row has a column proven not to fit."""
    prog, box, _ = arm
    off = {**box, "l2": (box["l2"][0] + 0.01, box["l2"][1] + 0.01)}
    r = residual_ranges(prog, off)
    rows = np.array(r.rows)
    assert all(r.outside()[rows == k].any() for k in range(1, 13))
