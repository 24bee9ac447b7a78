"""An empty relaxation is proven empty (lp/bounds.py `_farkas`): where HiGHS finds the LP
infeasible, its dual ray is checked in rigorous arithmetic, and the bounds then cross (the
solve ends "infeasible"). It used to give the box's own bounds: the data of Test A with its
joints exact, four times below their smallest consistent bound, stayed "contracted".

Soundness: on random relaxations that hold a known point (made so in exact arithmetic), the
bounds never cross and always hold the point; on relaxations made empty by two rows whose
sides are apart, they always cross."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from calib_dsl.lp.bounds import lp_bounds
from calib_dsl.relax.relaxation import LinearRelaxation, Rows
from calib_dsl.settings import LPSettings

NONE = np.zeros(0, dtype=np.int64)


def relaxation(A: np.ndarray, b_lo: np.ndarray, b: np.ndarray) -> LinearRelaxation:
    n = A.shape[1]
    return LinearRelaxation(Rows.join(A, NONE, NONE, np.zeros(0), 0), b, -np.ones(n),
                            np.ones(n), n, b_lo=b_lo)


def bounds(rel: LinearRelaxation) -> tuple[np.ndarray, np.ndarray]:
    return lp_bounds(rel, np.eye(rel.A.shape[1]), LPSettings(workers=1))


def exact_row(a: np.ndarray, x: np.ndarray) -> Fraction:
    return sum((Fraction(float(u)) * Fraction(float(v)) for u, v in zip(a, x, strict=True)),
               Fraction(0))


matrices = st.integers(2, 5).flatmap(lambda n: st.tuples(
    st.lists(st.lists(st.floats(-3, 3, allow_nan=False), min_size=n, max_size=n),
             min_size=1, max_size=8),
    st.lists(st.floats(-0.9, 0.9, allow_nan=False), min_size=n, max_size=n)))


@settings(max_examples=60, deadline=None)
@given(matrices, st.floats(0.0, 0.5), st.integers(0, 2**31))
def test_a_relaxation_holding_a_point_is_never_proven_empty(data, slack, seed):
    rows, point = data
    A, x = np.array(rows), np.array(point)
    rng = np.random.default_rng(seed)
    # each row's sides around its exact value at x: the point is inside every row
    at = np.array([float(exact_row(a, x)) for a in A])
    b_lo = np.nextafter(at - slack * rng.uniform(0, 1, len(at)), -np.inf)
    b_up = np.nextafter(at + slack * rng.uniform(0, 1, len(at)), np.inf)
    lo, hi = bounds(relaxation(A, b_lo, b_up))
    assert np.all(lo <= x) and np.all(x <= hi), (lo, x, hi)


@settings(max_examples=40, deadline=None)
@given(matrices, st.floats(1e-6, 1.0))
def test_two_rows_whose_sides_are_apart_are_proven_empty(data, gap):
    rows, _ = data
    A = np.array(rows)
    # (a row of tiny entries, 1e-50, is left to HiGHS's presolve, whose ray may be missing:
    # no proof then, which is sound; the property asked is of rows of ordinary magnitude)
    a = A[0] if np.max(np.abs(A[0])) >= 0.1 else np.ones(A.shape[1])
    # a.p <= 0 and a.p >= gap: no point at all; the other rows as wide as the box allows
    A2 = np.vstack([a, a, A[1:]])
    gap = gap * 0.5 * float(np.abs(a).sum())  # each row alone holds points of the box
    wide = np.abs(A2).sum(axis=1) + 1
    b_lo = np.r_[-wide[0], gap, -wide[2:]]
    b_up = np.r_[0.0, wide[1], wide[2:]]
    lo, hi = bounds(relaxation(A2, b_lo, b_up))
    assert np.any(lo > hi), (lo, hi)
