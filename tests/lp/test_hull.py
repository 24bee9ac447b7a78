"""lp/hull.py: the hull of a polytope along its coordinates, and the rows that hold it."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from calib_dsl.lp.hull import HullFailed, linear_hull


def test_a_diamond_and_a_row_that_holds_nothing():
    # |x| + |y| <= 1 as two two-sided rows, and x <= 5, which no optimum touches
    A = np.array([[1.0, 1.0], [1.0, -1.0], [1.0, 0.0]])
    hull = linear_hull(A, np.array([-1.0, -1.0, -np.inf]), np.array([1.0, 1.0, 5.0]),
                       np.full(2, -np.inf), np.full(2, np.inf))
    assert np.allclose(hull.lo, [-1, -1]) and np.allclose(hull.hi, [1, 1])
    assert hull.weight[2] == 0 and hull.weight[0] > 0 and hull.weight[1] > 0
    assert hull.points.shape == (4, 2)


def test_column_bounds_and_a_subset_of_columns():
    A = np.array([[1.0, 1.0]])
    hull = linear_hull(A, None, np.array([1.0]), np.array([0.0, 0.0]), np.array([2.0, 0.25]),
                       [0])
    assert hull.lo.tolist() == [0.0] and hull.hi.tolist() == [1.0]


def test_an_empty_polytope_is_said():
    with pytest.raises(HullFailed):
        linear_hull(np.array([[1.0]]), np.array([2.0]), np.array([3.0]), np.array([0.0]),
                    np.array([1.0]))


@given(st.integers(2, 5), st.integers(0, 10_000))
def test_every_point_of_the_polytope_lies_in_its_hull(n, seed):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(3 * n, n))
    x0 = rng.uniform(-1, 1, size=n)  # a point inside: every row's slab holds it
    half = rng.uniform(0.1, 1.0, size=3 * n)
    hull = linear_hull(A, A @ x0 - half, A @ x0 + half, np.full(n, -10.0), np.full(n, 10.0))
    assert np.all(hull.lo <= x0 + 1e-9) and np.all(x0 <= hull.hi + 1e-9)
    for x in hull.points:  # the optima are points of the polytope
        assert np.all(np.abs(A @ (x - x0)) <= half + 1e-7)
