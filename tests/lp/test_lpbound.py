"""lp/: every certified bound is >= the true maximum, whatever the dual guess.

The true maximum is known exactly in two ways:
- LPs built with a known optimal vertex and an exact KKT certificate (small integers and
  quarter-integers, so every product and sum is exact in floating point);
- random float LPs with a known feasible point, against linprog (HiGHS) and against the
  objective at many random points proven feasible in exact rational arithmetic.
Every comparison "bound >= c.x" is exact (fractions), never up to a tolerance.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import replace
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy import sparse
from scipy.optimize import linprog

from calib_dsl.lp.bounds import lp_bounds
from calib_dsl.lp.certify import (
    Certificates,
    box_max_up,
    box_maxes_up,
    certified_max,
    certified_maxes,
    dot_up,
    reused_bounds,
)
from calib_dsl.relax.relaxation import LinearRelaxation, Rows, transpose_times
from calib_dsl.settings import LPSettings

SETTINGS = settings(max_examples=150, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])
# HiGHS's simplex (warm, from the last basis) and its interior point method (the tight
# strategy's wide rounds): the bounds are certified either way
SOLVERS = st.sampled_from(["simplex", "ipm"])
GAMMA = 1e-13  # generous float rounding budget of a short dot product (n * 2^-53, n < 100)


# -- exact arithmetic ---------------------------------------------------------------------------

def fr(x: float) -> Fraction:
    return Fraction(float(x))


def exact_dot(a: np.ndarray, x: np.ndarray) -> Fraction:
    return sum((fr(ai) * fr(xi) for ai, xi in zip(a, x, strict=True) if ai != 0 and xi != 0),
               Fraction(0))


def le_exact(a: np.ndarray, x: np.ndarray, bound: float) -> bool:
    """a.x <= bound in exact arithmetic (a float filter first, exact when it cannot decide)."""
    if math.isnan(bound):
        return False
    if bound == math.inf:
        return True
    s = float(a @ x)
    err = GAMMA * float(np.abs(a) @ np.abs(x)) + 1e-300
    if s + err <= bound:
        return True
    if bound == -math.inf or s - err > bound:
        return False
    return exact_dot(a, x) <= fr(bound)


def ge_exact(a: np.ndarray, x: np.ndarray, bound: float) -> bool:
    """a.x >= bound exactly."""
    return le_exact(-a, x, -bound)


def feasible_exact(A: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                   x: np.ndarray) -> bool:
    if not (np.all(lo <= x) and np.all(x <= hi) and np.all(np.isfinite(x))):
        return False
    return all(le_exact(A[i], x, b[i]) for i in range(A.shape[0]))


def rows_of(A: np.ndarray) -> Rows:
    none = np.zeros(0, dtype=np.int64)
    return Rows.join(np.asarray(A, dtype=float), none, none, np.zeros(0), 0)


def rel_of(A: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray,
           main: int | None = None) -> LinearRelaxation:
    return LinearRelaxation(rows_of(A), np.asarray(b, dtype=float),
                            np.asarray(lo, dtype=float), np.asarray(hi, dtype=float),
                            A.shape[1] if main is None else main)


def feasible_samples(rng: np.random.Generator, A, b, lo, hi, anchors, count=300):
    """Points of {A x <= b, lo <= x <= hi} found by rejection sampling (uniform in the box,
    and around the known feasible anchors), each proven feasible exactly."""
    n = A.shape[1]
    flo = np.where(np.isfinite(lo), lo, -50.0)
    fhi = np.where(np.isfinite(hi), hi, 50.0)
    pts = [rng.uniform(flo, fhi) for _ in range(count)]
    for a in anchors:
        for scale in (1e-8, 1e-4, 1e-2, 1.0):
            pts += [a + scale * rng.standard_normal(n) for _ in range(count // 16)]
            pts += [a + scale * rng.choice([-1.0, 0.0, 1.0], size=n) for _ in range(4)]
    pts += list(anchors)
    out = [np.clip(p, lo, hi) for p in pts]
    return [p for p in out if feasible_exact(A, b, lo, hi, p)]


# -- LPs with a known optimum -------------------------------------------------------------------

def kkt_lp(rng: np.random.Generator, n: int, m: int, unbounded: bool, both: bool = False):
    """max c.x over {A x <= b, lo <= x <= hi} with optimum x_hat, optimal dual y_hat and value
    c.x_hat, all exact: integer A, quarter-integer points, integer multipliers."""
    x_hat = rng.integers(-20, 21, size=n) / 4.0
    A = rng.integers(-4, 5, size=(m, n)).astype(float)
    A[rng.random((m, n)) < 0.3] = 0.0
    if m >= 2 and rng.random() < 0.3:
        A[-1] = A[0]  # a duplicated row (degenerate)
    if m >= 1 and rng.random() < 0.2:
        A[rng.integers(m)] = 0.0  # an empty row
    active = rng.random(m) < 0.6
    slack = rng.integers(1, 12, size=m) / 4.0
    b = A @ x_hat + np.where(active, 0.0, slack)
    y_hat = np.where(active, rng.integers(0, 4, size=m), 0).astype(float)
    status = rng.choice(["lower", "upper", "fixed", "interior"], size=n)
    width = rng.integers(1, 9, size=n) / 4.0
    lo = np.where(status == "lower", x_hat, x_hat - width)
    hi = np.where(status == "upper", x_hat, x_hat + width)
    lo = np.where(status == "fixed", x_hat, lo)
    hi = np.where(status == "fixed", x_hat, hi)
    if unbounded:  # some infinite bounds; `both`: only free columns (both bounds infinite)
        free = rng.random(n) < 0.4
        if both:
            lo = np.where(free & (status == "interior"), -np.inf, lo)
            hi = np.where(free & (status == "interior"), np.inf, hi)
        else:
            lo = np.where(free & (status != "lower") & (status != "fixed"), -np.inf, lo)
            free = rng.random(n) < 0.4
            hi = np.where(free & (status != "upper") & (status != "fixed"), np.inf, hi)
    z = rng.integers(0, 4, size=n).astype(float)
    z = np.where(status == "upper", z, np.where(status == "lower", -z, 0.0))
    z = np.where(status == "fixed", rng.integers(-3, 4, size=n), z)
    c = A.T @ y_hat + z
    best = exact_dot(c, x_hat)
    assert float(best) == float(c @ x_hat)  # every number here is exact in floating point
    return A, b, lo, hi, c, x_hat, y_hat, best


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 6), m=st.integers(0, 8),
       unbounded=st.booleans())
def test_certified_max_is_an_upper_bound_with_any_dual_known_optimum(seed, n, m, unbounded):
    rng = np.random.default_rng(seed)
    A, b, lo, hi, c, x_hat, y_hat, best = kkt_lp(rng, n, m, unbounded)
    rel = rel_of(A, b, lo, hi)
    guesses = {
        "exact dual": y_hat,
        "zero": np.zeros(m),
        "perturbed": y_hat * (1 + 0.3 * rng.standard_normal(m)) + 0.05 * rng.random(m),
        "random": rng.exponential(2.0, size=m),
        "huge": rng.exponential(1e6, size=m),
        "tiny": rng.exponential(1e-12, size=m),
        "negative and non-finite entries": np.where(
            rng.random(m) < 0.5, -rng.exponential(size=m),
            rng.choice([np.nan, np.inf, -np.inf, 1.0], size=m)),
    }
    for name, y in guesses.items():
        bound = certified_max(rel, c, y)
        assert not math.isnan(bound), name
        assert bound == math.inf or fr(bound) >= best, (name, bound, float(best))
    # all guesses at once, by the dense product, row by row on the sparse matrix, and on a
    # matrix whose every entry is stored as two halves (a repeated entry: not summed)
    Y = np.array(list(guesses.values())).reshape(len(guesses), m)
    C = np.tile(c, (len(guesses), 1))
    r, k = np.nonzero(A)
    indptr = np.concatenate([[0], np.cumsum(2 * np.bincount(r, minlength=m))])
    halves = LinearRelaxation(Rows(np.repeat(A[r, k] / 2, 2), np.repeat(k, 2), indptr, A.shape),
                              b, lo, hi, n)
    dense_limit = LPSettings().dense_entries
    for limit, relax in ((dense_limit, rel), (0, rel), (dense_limit, halves)):
        for name, bound in zip(guesses, certified_maxes(relax, C, Y, limit), strict=True):
            assert not math.isnan(bound), name
            assert bound == math.inf or fr(bound) >= best, (name, limit, float(best))
    if np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)):
        # The exact dual gives the optimum itself, up to the rounding pad.
        bound = certified_max(rel, c, y_hat)
        assert bound <= float(best) + 1e-6 * (1 + abs(float(best)) + np.abs(c).sum()), bound
        # y = 0 gives the box's own bound (padded by the rounding budget).
        zero = certified_max(rel, c, np.zeros(m))
        assert box_max_up(c, c, lo, hi) <= zero <= box_max_up(c, c, lo, hi) + 1e-6 * (
            1 + float(np.abs(c) @ np.maximum(np.abs(lo), np.abs(hi))))


# 15 examples here; bench/checks/test_soundness_full.py runs 150
@settings(SETTINGS, max_examples=15)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 5), m=st.integers(0, 7),
       unbounded=st.booleans(), nuisance=st.integers(0, 2), solver=SOLVERS)
def test_lp_bounds_bracket_known_optimum_and_feasible_points(seed, n, m, unbounded, nuisance,
                                                             solver):
    rng = np.random.default_rng(seed)
    # half-infinite columns crash lp_bounds (see test_lp_bounds_half_infinite_column below)
    A, b, lo, hi, c, x_hat, _, best = kkt_lp(rng, n, m, unbounded, both=True)
    main = n - min(nuisance, n - 1)  # the last columns are nuisance variables (no cost)
    c = np.concatenate([c[:main], np.zeros(n - main)])
    objectives = np.vstack([c[:main], rng.integers(-3, 4, size=(3, main)).astype(float),
                            np.eye(main)])
    skip = rng.random(len(objectives)) < 0.25
    rel = rel_of(A, b, lo, hi, main)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lower, upper = lp_bounds(rel, objectives, skip=skip, solver=solver)
    points = feasible_samples(rng, A, b, lo, hi, [x_hat], count=150)
    assert any(np.array_equal(p, x_hat) for p in points)
    for i, obj in enumerate(objectives):
        full = np.concatenate([obj, np.zeros(n - main)])
        box_up = box_max_up(full, full, lo, hi)
        box_dn = -box_max_up(-full, -full, lo, hi)
        if skip[i]:
            assert (lower[i], upper[i]) == (box_dn, box_up)
        else:
            assert box_dn <= lower[i] and upper[i] <= box_up  # never worse than the box
        for p in points:
            assert ge_exact(full, p, lower[i]) and le_exact(full, p, upper[i]), (i, p)
    if main == n and not skip[0]:
        # the first objective has a known maximum: certified, and HiGHS makes it tight
        assert upper[0] == math.inf or fr(upper[0]) >= best
        if np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)):
            assert upper[0] <= float(best) + 1e-6 * (1 + abs(float(best)))


# -- random float LPs -----------------------------------------------------------------------

def random_float_lp(rng: np.random.Generator, n: int, m: int, infinite: bool,
                    both: bool = False):
    x0 = rng.uniform(-3, 3, size=n)
    lo = x0 - rng.exponential(1.0, size=n) * rng.choice([0.0, 1.0], p=[0.15, 0.85], size=n)
    hi = x0 + rng.exponential(1.0, size=n) * rng.choice([0.0, 1.0], p=[0.15, 0.85], size=n)
    if infinite:
        lo = np.where(rng.random(n) < 0.3, -np.inf, lo)
        hi = np.where(rng.random(n) < 0.3, np.inf, hi)
        if both:  # only free columns: half-infinite ones crash lp_bounds (see below)
            free = np.isinf(lo) | np.isinf(hi)
            lo, hi = np.where(free, -np.inf, lo), np.where(free, np.inf, hi)
    A = rng.standard_normal((m, n)) * rng.choice([1e-3, 1.0, 1e3], size=(m, 1))
    A[rng.random((m, n)) < 0.25] = 0.0
    slack = rng.exponential(0.5, size=m) * (rng.random(m) < 0.6)
    b = A @ x0 + slack
    for i in range(m):  # make x0 exactly feasible (b was rounded)
        while not le_exact(A[i], x0, b[i]):
            b[i] = np.nextafter(b[i], np.inf)
    c = rng.standard_normal(n) * rng.choice([1e-3, 1.0, 1e3])
    return A, b, lo, hi, c, x0


def linprog_max(A, b, lo, hi, c):
    """max c.x by HiGHS (not trusted): value, argmax, and the dual y >= 0 of the rows."""
    m, n = A.shape
    res = linprog(-c, A_ub=A if m else None, b_ub=b if m else None,
                  bounds=list(zip(np.where(np.isfinite(lo), lo, None),
                                  np.where(np.isfinite(hi), hi, None), strict=True)),
                  method="highs")
    if res.status != 0:
        return None
    y = -res.ineqlin.marginals if m else np.zeros(0)
    return -res.fun, res.x, y


# 25 examples here; bench/checks/test_soundness_full.py runs 250
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 6), m=st.integers(1, 8),
       infinite=st.booleans())
def test_certified_max_random_float_lps(seed, n, m, infinite):
    rng = np.random.default_rng(seed)
    A, b, lo, hi, c, x0 = random_float_lp(rng, n, m, infinite)
    rel = rel_of(A, b, lo, hi)
    sol = linprog_max(A, b, lo, hi, c)
    ys = {"zero": np.zeros(m), "random": rng.exponential(1.0, size=m),
          "sparse random": rng.exponential(1.0, size=m) * (rng.random(m) < 0.5)}
    if sol is not None:
        val, xs, y = sol
        ys["exact dual"] = y
        ys["perturbed dual"] = y * (1 + 0.1 * rng.standard_normal(m))
        ys["shifted dual"] = y + 0.01 * rng.random(m)
        ys["dual, rounded"] = np.round(y, 3)
    points = feasible_samples(rng, A, b, lo, hi, [x0] + ([sol[1]] if sol else []), count=200)
    assert any(np.array_equal(p, x0) for p in points)
    for name, y in ys.items():
        bound = certified_max(rel, c, y)
        assert not math.isnan(bound), name
        for p in points:
            assert le_exact(c, p, bound), (name, bound, float(c @ p))
        if sol is not None:  # HiGHS' optimum holds to its feasibility tolerance only
            assert bound >= sol[0] - 1e-6 * (1 + abs(sol[0])), (name, bound, sol[0])
    if sol is not None and np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)):
        # tight up to HiGHS' own tolerances (1e-7, relative to the problem's magnitudes)
        y = ys["exact dual"]
        tight = certified_max(rel, c, y)
        scale = (1 + abs(sol[0]) + float(np.abs(y) @ np.abs(b))
                 + float((np.abs(c) + np.abs(A).T @ np.abs(y))
                         @ np.maximum(np.abs(lo), np.abs(hi))))
        assert tight <= sol[0] + 1e-5 * scale


# 15 examples here; bench/checks/test_soundness_full.py runs 150
@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 5), m=st.integers(1, 7),
       infinite=st.booleans(), solver=SOLVERS)
def test_lp_bounds_bracket_random_feasible_points(seed, n, m, infinite, solver):
    rng = np.random.default_rng(seed)
    A, b, lo, hi, _, x0 = random_float_lp(rng, n, m, infinite, both=True)
    objectives = np.vstack([np.eye(n), rng.standard_normal((3, n))])
    skip = rng.random(len(objectives)) < 0.2
    lower, upper = lp_bounds(rel_of(A, b, lo, hi), objectives, skip=skip, solver=solver)
    points = feasible_samples(rng, A, b, lo, hi, [x0], count=200)
    for i, c in enumerate(objectives):
        assert not (math.isnan(lower[i]) or math.isnan(upper[i]))
        for p in points:
            assert ge_exact(c, p, lower[i]) and le_exact(c, p, upper[i]), (i, lower[i], upper[i])
        if skip[i]:
            assert upper[i] == box_max_up(c, c, lo, hi)
            assert lower[i] == -box_max_up(-c, -c, lo, hi)


# 12 examples here; bench/checks/test_soundness_full.py runs 120
@settings(max_examples=12, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(8, 14), m=st.integers(1, 10))
def test_probe_points_change_no_bound(seed, n, m, monkeypatch):
    """With two workers, probe LPs first find points on many box bounds, and the objectives
    they reach are not solved: every bound still holds every feasible point, equals the one
    worker's bound (no probes) to the LP's tolerance, and every objective keeps a basis to
    start from next time (its own LP's, or the reaching point's)."""
    from calib_dsl.lp.bounds import _probe_points
    from calib_dsl.lp.certify import box_bounds

    rng = np.random.default_rng(seed)
    A, b, lo, hi, _, x0 = random_float_lp(rng, n, m, False)
    unseen = rng.random(n) < 0.5
    A[:, unseen] = 0.0  # unknowns no row sees: the probes reach their bounds
    b = np.maximum(b, A @ x0)
    for i in range(m):  # x0 still exactly feasible
        while not le_exact(A[i], x0, b[i]):
            b[i] = np.nextafter(b[i], np.inf)
    rel = rel_of(A, b, lo, hi)
    rel.keys, rel.col_keys = np.arange(m), np.arange(n)
    bounds, certs = {}, {}
    for workers in (1, 2):
        certs[workers] = Certificates()
        bounds[workers] = lp_bounds(rel, np.eye(n), LPSettings(workers=workers),
                                    certificates=certs[workers], probes=True)
    points = feasible_samples(rng, A, b, lo, hi, [x0], count=100)
    scale = 1.0 + np.maximum(np.abs(lo), np.abs(hi))
    for i in range(n):
        low, up = bounds[2][0][i], bounds[2][1][i]
        for p in points:
            assert low <= p[i] <= up  # unit objectives: exact comparisons
        assert abs(low - bounds[1][0][i]) <= 1e-6 * scale[i]
        assert abs(up - bounds[1][1][i]) <= 1e-6 * scale[i]
        for sign in (1.0, -1.0):
            assert (i, sign) in certs[2].basis
    tasks = box_bounds(rel, np.eye(n))[2]
    probes = np.array([p for p, _ in _probe_points(rel, tasks, LPSettings())])
    assert len(probes) >= 2
    assert np.all(probes[:, unseen].max(axis=0) == hi[unseen])
    assert np.all(probes[:, unseen].min(axis=0) == lo[unseen])


# -- special cases ----------------------------------------------------------------------------

def test_unbounded_column_gives_infinity_not_a_wrong_value():
    # max x1 + x2 with x1 <= 1, x2 free: unbounded, so only +inf is a valid bound
    A = np.array([[1.0, 0.0]])
    rel = rel_of(A, [1.0], [0.0, -np.inf], [5.0, np.inf])
    for y in ([0.0], [1.0], [1e9]):
        assert certified_max(rel, np.array([1.0, 1.0]), np.array(y)) == math.inf
    lower, upper = lp_bounds(rel, np.array([[1.0, 1.0], [1.0, 0.0]]))
    assert upper[0] == math.inf and lower[0] <= 0.0
    # sound; not tight: any free column makes every certificate +oo (the rounding pad of the
    # residual c - A'y is > 0 in every component), so the box bound 5 is kept
    assert 1.0 <= upper[1] <= 5.0 + 1e-6 and lower[1] <= 0.0


def test_lower_bound_with_an_infinite_box():
    # min x over {x >= 2 (as -x <= -2)}, x in ]-oo, oo[: the LP finds 2; any bound <= 2 is right
    rel = rel_of(np.array([[-1.0]]), [-2.0], [-np.inf], [np.inf])
    lower, upper = lp_bounds(rel, np.array([[1.0]]))
    assert lower[0] <= 2.0 and upper[0] == math.inf


def test_skipped_ends_keep_the_box_bound_and_the_others_get_their_lps():
    # |x| + |y| <= 1 over [-2, 2]^2: every end is +-1 by its LP and +-2 by the box, so each
    # end shows whether it was solved; flags per end (max, min), or one per objective
    rel = rel_of(np.array([[1.0, 1.0], [1.0, -1.0], [-1.0, 1.0], [-1.0, -1.0]]),
                 [1.0] * 4, [-2.0, -2.0], [2.0, 2.0])
    lower, upper = lp_bounds(rel, np.eye(2), skip=np.array([[False, True], [True, False]]))
    assert upper[0] == pytest.approx(1.0, abs=1e-6) and lower[0] == pytest.approx(-2.0, abs=1e-6)
    assert upper[1] == pytest.approx(2.0, abs=1e-6) and lower[1] == pytest.approx(-1.0, abs=1e-6)
    lower, upper = lp_bounds(rel, np.eye(2), skip=np.array([False, True]))  # (per unknown)
    assert upper[0] == pytest.approx(1.0, abs=1e-6) and lower[0] == pytest.approx(-1.0, abs=1e-6)
    assert (lower[1], upper[1]) == pytest.approx((-2.0, 2.0), abs=1e-6)
    lower, upper = lp_bounds(rel, np.zeros((0, 2)), skip=np.zeros((0, 2), dtype=bool))
    assert lower.shape == upper.shape == (0,)  # (no objective: nothing to solve)


def test_an_infeasible_relaxation_is_proven_empty():
    # x <= -1 and -x <= -1 (x >= 1): no point at all; HiGHS's dual ray proves it (the bounds
    # cross), where they used to fall back to the box (tests/lp/test_farkas.py: soundness)
    A = np.array([[1.0, 0.0], [-1.0, 0.0]])
    rel = rel_of(A, [-1.0, -1.0], [-3.0, -2.0], [3.0, 2.0])
    lower, upper = lp_bounds(rel, np.eye(2))
    assert np.any(lower > upper)


def test_degenerate_fixed_box_and_zero_objective():
    A = np.array([[1.0, 1.0], [1.0, 1.0], [0.0, 0.0]])
    rel = rel_of(A, [2.0, 2.0, 0.0], [1.0, 1.0], [1.0, 1.0])
    lower, upper = lp_bounds(rel, np.array([[1.0, 0.0], [0.0, 0.0], [1.0, -1.0]]))
    assert lower[0] <= 1.0 <= upper[0] and upper[0] - lower[0] < 1e-8
    assert lower[1] <= 0.0 <= upper[1]
    assert lower[2] <= 0.0 <= upper[2]
    assert certified_max(rel, np.zeros(2), np.array([1.0, 0.0, 5.0])) >= 0.0


def test_empty_relaxation_no_rows():
    rel = LinearRelaxation(sparse.csr_matrix((0, 3)), np.zeros(0), np.array([-1.0, 0.0, 2.0]),
                           np.array([1.0, 0.5, 2.0]), 3)
    lower, upper = lp_bounds(rel, np.eye(3))
    assert np.all(lower <= [-1.0, 0.0, 2.0]) and np.all(upper >= [1.0, 0.5, 2.0])
    assert certified_max(rel, np.array([1.0, -1.0, 1.0]), np.zeros(0)) >= 3.0


# -- the rounding-error bounds -----------------------------------------------------------------

finite = st.floats(-1e100, 1e100, allow_nan=False, allow_subnormal=True)


@settings(max_examples=400, deadline=None)
@given(st.lists(st.tuples(finite, finite), min_size=0, max_size=12))
def test_dot_up_bounds_the_exact_dot_product(pairs):
    x = np.array([p[0] for p in pairs], dtype=float)
    y = np.array([p[1] for p in pairs], dtype=float)
    up = dot_up(x, y)
    assert not math.isnan(up)
    assert up == math.inf or fr(up) >= exact_dot(x, y)


@settings(max_examples=400, deadline=None)
@given(st.lists(st.tuples(finite, finite, finite, finite), min_size=0, max_size=8),
       st.data())
def test_box_max_up_bounds_the_exact_maximum(rows, data):
    r1 = np.array([t[0] for t in rows], dtype=float)
    r2 = np.array([t[1] for t in rows], dtype=float)
    b1 = np.array([t[2] for t in rows], dtype=float)
    b2 = np.array([t[3] for t in rows], dtype=float)
    r_lo, r_hi = np.minimum(r1, r2), np.maximum(r1, r2)
    lo, hi = np.minimum(b1, b2), np.maximum(b1, b2)
    # some infinite bounds
    inf_lo = np.array(data.draw(st.lists(st.booleans(), min_size=len(rows), max_size=len(rows))),
                      dtype=bool)
    lo = np.where(inf_lo, -np.inf, lo)
    up = box_max_up(r_lo, r_hi, lo, hi)
    assert not math.isnan(up)
    if up == math.inf:
        return
    total = Fraction(0)
    for i in range(len(rows)):  # bilinear: the maximum is at a corner (0 * oo = 0)
        cands = []
        for r in (r_lo[i], r_hi[i]):
            for p in (lo[i], hi[i]):
                if r == 0 or p == 0:
                    cands.append(Fraction(0))
                elif math.isinf(p):
                    cands.append(None if r * p > 0 else "-inf")
                else:
                    cands.append(fr(r) * fr(p))
        assert None not in cands, "the maximum is +oo but the bound is finite"
        finite_c = [v for v in cands if isinstance(v, Fraction)]
        total += max(finite_c)
    assert fr(up) >= total


# -- known defects (not ours: calib_dsl/lpbound.py) --------------------------------------------

def test_dot_up_negative_overflow_is_not_minus_infinity():
    # x in [-1.5e308, 0], x <= -1e308, maximize 2x: the maximum is 2 * -1e308 = -2e308 (finite)
    rel = rel_of(np.array([[1.0]]), [-1e308], [-1.5e308], [0.0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        bound = certified_max(rel, np.array([2.0]), np.array([2.0]))
        assert bound > -math.inf
        assert dot_up(np.array([2.0]), np.array([-1e308])) > -math.inf


def test_box_max_up_all_negative_overflow_is_not_nan():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        up = box_max_up(np.array([1e200]), np.array([2e200]), np.array([-1e200]),
                        np.array([-5e199]))
    assert not math.isnan(up)


_HALF_INFINITE = """
import numpy as np
import pytest
from scipy import sparse
from calib_dsl.lp.bounds import lp_bounds
from calib_dsl.relax.relaxation import LinearRelaxation
A = np.array([[0.0, -1.7321348424395848], [0.0, -1.1632259734447486e-03],
              [-6.2928809406155450e-01, 0.0], [-7.1331337163224362e+02, 5.5337847035328946e+02],
              [-6.3085971925289158e+01, 0.0], [4.0963782655711697e+02, 8.2985530706132397e+02]])
b = np.array([-3.2003698278656567e+00, 1.8583141638349002e-01, -1.1516082514015915e+00,
              -2.8187073569454418e+02, -1.1544843530719298e+02, 2.2829284024282965e+03])
rel = LinearRelaxation(sparse.csr_matrix(A), b, np.array([1.830017542472281, -np.inf]),
                       np.array([1.830017542472281, 1.9628649739211919]), 2)
objectives = np.array([[1.0, 0.0], [0.0, 1.0], [2.4317325028452124, 0.6419163790823205],
                       [0.8449927337191754, 0.8406828762653401],
                       [-0.6066115359095516, -0.07002844663838208]])
lower, upper = lp_bounds(rel, objectives)
# x1 = 1.83 is fixed; row 1 gives x2 >= 1.8477, row 4 gives x2 <= 1.8496
assert lower[1] <= 1.8477 and upper[1] >= 1.8496, (lower, upper)
"""


def test_lp_bounds_half_infinite_column():
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-c", _HALF_INFINITE], capture_output=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr.decode()[-500:]


# -- two-sided rows (b_lo <= A x <= b): signed multipliers --------------------------------------

def two_sided_lp(rng: np.random.Generator, n: int, m: int):
    """A random float LP with rows bounded on one side, the other or both, and a point x0
    feasible by construction (every slack >= 0 before rounding; checked exactly after)."""
    x0 = rng.uniform(-3, 3, size=n)
    A = rng.standard_normal((m, n)) * (rng.random((m, n)) < 0.8)
    side = rng.choice(["both", "upper", "lower"], size=m)
    gap = rng.exponential(0.5, size=(2, m)) * (rng.random((2, m)) < 0.7)
    b, b_lo = sides_around(A @ x0, side != "lower", side != "upper", gap)
    lo, hi = x0 - rng.uniform(0.1, 4, size=n), x0 + rng.uniform(0.1, 4, size=n)
    rel = LinearRelaxation(sparse.csr_matrix(A), b, lo, hi, n, b_lo=b_lo)
    return rel, x0


def sides_around(ax: np.ndarray, upper: np.ndarray, lower: np.ndarray, gap: np.ndarray):
    """Row sides at gap[0] above and gap[1] below A x (infinite where a side is absent), each
    widened by 1e-9 |A x| so that x stays feasible after rounding."""
    b = np.where(upper, ax + gap[0] + 1e-9 * np.abs(ax), np.inf)
    b_lo = np.where(lower, ax - gap[1] - 1e-9 * np.abs(ax), -np.inf)
    return b, b_lo


# 20 examples here; bench/checks/test_soundness_full.py runs 200
@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 6), m=st.integers(1, 8),
       solver=SOLVERS)
def test_two_sided_rows_certify_with_signed_multipliers(seed, n, m, solver):
    rng = np.random.default_rng(seed)
    rel, x0 = two_sided_lp(rng, n, m)
    A1, b1 = rel.one_sided()
    A1 = A1.toarray()
    points = feasible_samples(rng, A1, b1, rel.lo, rel.hi, [x0], count=200)
    assert any(np.array_equal(p, x0) for p in points)
    c = rng.standard_normal(n)
    ys = {"zero": np.zeros(m), "signed random": rng.standard_normal(m) * 3,
          "wrong signs": -np.sign(rng.standard_normal(m)) * rng.exponential(1.0, size=m)}
    sol = linprog(-c, A_ub=A1, b_ub=b1, bounds=list(zip(rel.lo, rel.hi, strict=True)),
                  method="highs")
    if sol.status == 0:
        # fold the one-sided duals back onto the two-sided rows (upper side +, lower side -)
        y1 = -sol.ineqlin.marginals
        up = np.flatnonzero(np.isfinite(rel.b))
        dn = np.flatnonzero(np.isfinite(rel.b_lo))
        y = np.zeros(m)
        np.add.at(y, up, y1[:len(up)])
        np.add.at(y, dn, -y1[len(up):])
        ys["exact dual"] = y
    for name, y in ys.items():
        bound = certified_max(rel, c, y)
        assert not math.isnan(bound), name
        for p in points:
            assert le_exact(c, p, bound), (name, bound, float(c @ p))
        if name == "exact dual":
            assert bound <= -sol.fun + 1e-6 * (1 + abs(sol.fun) + np.abs(c) @ np.abs(x0)) * 10
    lower, upper = lp_bounds(rel, np.vstack([np.eye(n), c]), solver=solver)
    for i, obj in enumerate(np.vstack([np.eye(n), c])):
        for p in points:
            assert ge_exact(obj, p, lower[i]) and le_exact(obj, p, upper[i]), (i, lower, upper)
    if sol.status == 0:  # the LP's bound is near the optimum, not only sound
        assert upper[-1] <= -sol.fun + 1e-5 * (1 + abs(sol.fun) + np.abs(c) @ np.abs(x0))


# -- multipliers reused on another box (Certificates) -----------------------------------------

def nearby_lp(rng: np.random.Generator, rel: LinearRelaxation, x0: np.ndarray,
              keys: np.ndarray):
    """The same rows on another box, as a later round sees them: coefficients perturbed, new
    sides around a new feasible point, some rows gone; keys name the rows that stay."""
    n = rel.A.shape[1]
    A = rel.A.toarray()
    stay = np.sort(rng.choice(len(keys), size=rng.integers(0, len(keys) + 1), replace=False))
    A = (A + 0.1 * rng.standard_normal(A.shape) * (A != 0))[stay]
    x1 = x0 + rng.uniform(-0.5, 0.5, size=n)
    b, b_lo = sides_around(A @ x1, np.isfinite(rel.b[stay]), np.isfinite(rel.b_lo[stay]),
                           rng.exponential(0.3, size=(2, len(stay))))
    lo, hi = x1 - rng.uniform(0.05, 2, size=n), x1 + rng.uniform(0.05, 2, size=n)
    out = LinearRelaxation(sparse.csr_matrix(A.reshape(len(stay), n)), b, lo, hi, n, b_lo=b_lo,
                           keys=keys[stay], scale=rng.uniform(0.1, 3, size=n), family="f",
                           col_keys=np.arange(n))
    return out, x1


# 20 examples here; bench/checks/test_soundness_full.py runs 200
@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 5), m=st.integers(1, 8),
       solver=SOLVERS)
def test_reused_multipliers_bound_every_feasible_point_of_another_box(seed, n, m, solver):
    rng = np.random.default_rng(seed)
    rel, x0 = two_sided_lp(rng, n, m)
    keys = np.sort(rng.choice(10 * m, size=m, replace=False))
    rel.keys, rel.scale, rel.family = keys, rng.uniform(0.1, 3, size=n), "f"
    rel.col_keys = np.arange(n)
    certs = Certificates()
    lower, upper = lp_bounds(rel, np.eye(n), solver=solver, certificates=certs)
    if solver == "simplex":  # each LP solved left its final basis (the interior point: none),
        # and an objective that an LP point reached (not solved) that point's basis
        assert set(certs.basis) == {(i, s) for i in range(n) for s in (1.0, -1.0)}
        assert set(certs.y) <= set(certs.basis)
    # on the same relaxation the kept multipliers give the LPs' own bounds back
    rlo, rhi = reused_bounds(rel, np.eye(n), certs)
    solved = {i for i, _ in certs.y}
    for i in solved:  # (up to the rounding of y * scale / scale)
        assert abs(rlo[i] - lower[i]) <= 1e-9 * (1 + abs(lower[i]))
        assert abs(rhi[i] - upper[i]) <= 1e-9 * (1 + abs(upper[i]))
    later, x1 = nearby_lp(rng, rel, x0, keys)
    A1, b1 = later.one_sided()
    points = feasible_samples(rng, A1.toarray(), b1, later.lo, later.hi, [x1], count=200)
    assert any(np.array_equal(p, x1) for p in points)
    rlo, rhi = reused_bounds(later, np.eye(n), certs)
    for i, obj in enumerate(np.eye(n)):
        for p in points:
            assert ge_exact(obj, p, rlo[i]) and le_exact(obj, p, rhi[i]), (i, rlo, rhi)
    # the LPs again, each objective's simplex starting from its basis on the first box,
    # mapped onto the rows left (an "alien" basis, which HiGHS completes): as sound
    llo, lhi = lp_bounds(later, np.eye(n), certificates=certs)
    for i, obj in enumerate(np.eye(n)):
        for p in points:
            assert ge_exact(obj, p, llo[i]) and le_exact(obj, p, lhi[i]), (i, llo, lhi)
    # or from the optimum of the objective solved before (own_bases off): as sound
    flo, fhi = lp_bounds(later, np.eye(n), certificates=certs.copy(), own_bases=False)
    for i, obj in enumerate(np.eye(n)):
        for p in points:
            assert ge_exact(obj, p, flo[i]) and le_exact(obj, p, fhi[i]), (i, flo, fhi)
    # another family's multipliers are not used: the box's own bounds
    later.family = "g"
    rlo, rhi = reused_bounds(later, np.eye(n), certs)
    assert np.allclose(rlo, later.lo, rtol=1e-8) and np.allclose(rhi, later.hi, rtol=1e-8)


def test_reused_multipliers_scale_with_the_columns_unit():
    # x in [0, 10] with 1 <= x <= 2 (rows key 7): the multiplier of the bound on x per unit of
    # x; on a box whose column is x / 4 (scale 4), the same row bounds it by 2 / 4
    rel = LinearRelaxation(rows_of(np.array([[1.0]])), np.array([2.0]), np.array([0.0]),
                           np.array([10.0]), 1, b_lo=np.array([1.0]), keys=np.array([7]),
                           scale=np.array([1.0]), family="f")
    certs = Certificates()
    lo, hi = lp_bounds(rel, np.eye(1), certificates=certs)
    assert lo[0] <= 1.0 and hi[0] >= 2.0 and hi[0] - lo[0] < 1.0 + 1e-6
    quarter = LinearRelaxation(rows_of(np.array([[4.0]])), np.array([2.0]), np.array([0.0]),
                               np.array([2.5]), 1, b_lo=np.array([1.0]), keys=np.array([7]),
                               scale=np.array([4.0]), family="f")
    lo, hi = reused_bounds(quarter, np.eye(1), certs)
    assert lo[0] <= 0.25 and hi[0] >= 0.5 and hi[0] - lo[0] < 0.25 + 1e-6
    gone = LinearRelaxation(rows_of(np.array([[4.0]])), np.array([2.0]), np.array([0.0]),
                            np.array([2.5]), 1, b_lo=np.array([1.0]), keys=np.array([8]),
                            scale=np.array([4.0]), family="f")
    lo, hi = reused_bounds(gone, np.eye(1), certs)  # row 7 is not there: the box
    assert np.allclose([lo[0], hi[0]], [0.0, 2.5], rtol=1e-8, atol=1e-12)
    # multipliers of a relaxation without rows (the box alone) reused on one with rows
    empty = LinearRelaxation(rows_of(np.zeros((0, 1))), np.zeros(0), np.array([0.0]),
                             np.array([10.0]), 1, b_lo=np.zeros(0),
                             keys=np.zeros(0, np.int64), family="f")
    certs = Certificates()
    lp_bounds(empty, np.eye(1), certificates=certs)
    lo, hi = reused_bounds(quarter, np.eye(1), certs)
    assert np.allclose([lo[0], hi[0]], [0.0, 2.5], rtol=1e-8, atol=1e-12)


# -- the row-sparse matrix the tight strategy builds (no scipy.sparse on its path) -----------

@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 7), st.integers(0, 5), st.integers(0, 6))
def test_rows_agree_with_dense_matrices(seed, m, k, width):
    rng = np.random.default_rng(seed)
    dense = rng.normal(size=(m, k)) * (rng.random((m, k)) < 0.6)
    nnz = int(rng.integers(0, 2 * m * width + 1)) if m and width else 0
    rows, cols = rng.integers(0, max(m, 1), nnz), rng.integers(0, max(width, 1), nnz)
    vals = rng.normal(size=nnz)
    full = np.zeros((m, k + width))
    full[:, :k] = dense
    np.add.at(full, (rows, k + cols), vals)  # repeated (row, column) pairs add up
    mags = np.abs(full)  # |A| entry by entry, as stored: a repeated pair's magnitudes add up
    mags[:, k:] = 0.0
    np.add.at(mags, (rows, k + cols), np.abs(vals))
    A = Rows.join(dense, rows, cols, vals, width)
    assert A.shape == (m, k + width)
    back = sparse.csr_matrix((A.data, A.indices, A.indptr), shape=A.shape).toarray()
    assert np.allclose(back, full, rtol=0, atol=1e-12)
    assert np.array_equal(A.row_nonzeros() > 0, np.any(back != 0, axis=1) | (
        np.bincount(rows, minlength=m) > 0 if m else np.zeros(0, bool)))
    y = rng.normal(size=m)
    assert np.allclose(transpose_times(A, y), full.T @ y, atol=1e-12)
    assert np.allclose(transpose_times(A, y, absolute=True), mags.T @ y, atol=1e-12)
    pick = rng.permutation(m)[: int(rng.integers(0, m + 1))] if m else np.zeros(0, np.int64)
    sub = A.take(pick)
    got = sparse.csr_matrix((sub.data, sub.indices, sub.indptr), shape=sub.shape).toarray()
    assert np.array_equal(got, back[pick])


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(1, 40), st.integers(1, 6))
def test_products_with_mostly_zero_multipliers_match_the_dense_ones(seed, m, n):
    # an LP's multipliers are nonzero on its binding rows only: transpose_times reads those
    # rows alone, and the row generation's check (RowCheck) multiplies by sparse products
    from calib_dsl.lp.highs import RowCheck

    rng = np.random.default_rng(seed)
    full = rng.normal(size=(m, n)) * (rng.random((m, n)) < 0.5) * 10.0 ** rng.integers(-4, 5)
    A = sparse.csr_matrix(full)
    R = Rows(A.data, A.indices, A.indptr, A.shape)
    y = rng.normal(size=m) * (rng.random(m) < 0.2)
    for M in (A, R):
        assert np.allclose(transpose_times(M, y), full.T @ y, rtol=1e-12, atol=1e-300)
        assert np.allclose(transpose_times(M, np.abs(y), absolute=True),
                           np.abs(full).T @ np.abs(y), rtol=1e-12, atol=1e-300)
    x = rng.normal(size=n)
    b = full @ x + rng.normal(size=m)
    rel = LinearRelaxation(R, b, -np.ones(n), np.ones(n))
    inside = rng.permutation(m)[: int(rng.integers(0, m + 1))]
    excess = full @ x - b - (1e-9 * (np.abs(full) @ np.abs(x)) + 1e-12)
    excess[inside] = 0.0
    want = np.flatnonzero(excess > 0)
    got = RowCheck(rel, m).violated(x, inside)
    assert sorted(got.tolist()) == want.tolist()
    assert np.all(np.diff(excess[got]) <= 0)  # the most violated first
    assert len(RowCheck(rel, 2).violated(x, inside)) == min(2, len(want))


def test_a_scipy_matrix_is_accepted_where_rows_are():
    A = np.array([[1.0, 1.0], [1.0, -1.0]])
    lo, hi = np.array([-5.0, -5.0]), np.array([5.0, 5.0])
    ours = lp_bounds(rel_of(A, [1.0, 1.0], lo, hi), np.eye(2))
    theirs = lp_bounds(LinearRelaxation(sparse.csr_matrix(A), np.array([1.0, 1.0]), lo, hi, 2),
                       np.eye(2))
    assert np.array_equal(ours[0], theirs[0]) and np.array_equal(ours[1], theirs[1])
    assert ours[1][0] >= 1.0 and ours[1][0] < 5.0  # x1 <= 1 is certified, and used


# -- row generation: a tall LP solved from a subset of its rows ---------------------------

# 6 examples here; bench/checks/test_soundness_full.py runs 60
@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 5), m=st.integers(10, 120),
       two_sided=st.booleans(), solver=SOLVERS, primal=st.booleans())
def test_row_generation_gives_the_full_lps_bounds(seed, n, m, two_sided, solver, primal):
    """(Row generation keeps to the simplex whatever solver is asked for: it re-solves after
    adding rows, from the last basis; `primal`: the primal simplex, which tall LPs with many
    columns run, else the dual.)"""
    rng = np.random.default_rng(seed)
    x_hat = rng.uniform(-1, 1, n)  # a feasible point: every row holds it with some room
    A = rng.normal(size=(m, n)) * (rng.random((m, n)) < 0.7)
    ax = A @ x_hat
    b = ax + rng.exponential(0.5, m)
    b_lo = ax - rng.exponential(0.5, m) if two_sided else None
    lo, hi = np.full(n, -3.0), np.full(n, 3.0)
    rel = LinearRelaxation(rows_of(A), b, lo, hi, n, b_lo=b_lo)
    objectives = np.vstack([np.eye(n), rng.normal(size=(2, n))])
    full = lp_bounds(rel, objectives, LPSettings(rows_at_once=10**9))
    small = LPSettings(rows_at_once=4, rows_added=int(rng.integers(1, 6)),  # many small passes
                       tall_primal_columns=1 if primal else 10**9)
    gen = lp_bounds(rel, objectives, small, solver=solver)
    scale = 1e-7 * (1 + np.abs(objectives).sum(axis=1) * 3)
    assert np.all(np.abs(gen[0] - full[0]) <= scale), (gen[0], full[0])
    assert np.all(np.abs(gen[1] - full[1]) <= scale), (gen[1], full[1])
    two = b_lo if b_lo is not None else np.full(m, -np.inf)
    A_all = np.vstack([A, -A[np.isfinite(two)]])
    b_all = np.concatenate([b, -two[np.isfinite(two)]])
    points = feasible_samples(rng, A_all, b_all, lo, hi, [x_hat], count=100)
    for p in points:  # sound: every feasible point's objective lies within the bounds
        for i, obj in enumerate(objectives):
            assert le_exact(obj, p, gen[1][i]) and ge_exact(obj, p, gen[0][i])


# 6 examples here; bench/checks/test_soundness_full.py runs 60
@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 5), m=st.integers(10, 80),
       primal=st.booleans())
def test_row_generation_from_the_last_rounds_binding_rows(seed, n, m, primal):
    """A later round's tall LPs start from the rows the same objectives bound on before (by
    key, on a nearby LP with rows gone): the full LP's bounds all the same, and sound."""
    rng = np.random.default_rng(seed)
    rel, x0 = two_sided_lp(rng, n, m)
    keys = np.sort(rng.choice(10 * m, size=m, replace=False))
    rel.keys, rel.scale, rel.family, rel.col_keys = keys, np.ones(n), "f", np.arange(n)
    certs = Certificates()
    small = LPSettings(rows_at_once=4, rows_added=int(rng.integers(1, 6)),
                       tall_primal_columns=1 if primal else 10**9)
    lp_bounds(rel, np.eye(n), small, certificates=certs)
    later, x1 = nearby_lp(rng, rel, x0, keys)
    full = lp_bounds(later, np.eye(n), LPSettings(rows_at_once=10**9))
    gen = lp_bounds(later, np.eye(n), small, certificates=certs)
    span = 1e-7 * (1 + np.abs(later.lo) + np.abs(later.hi))
    assert np.all(np.abs(gen[0] - full[0]) <= span), (gen[0], full[0])
    assert np.all(np.abs(gen[1] - full[1]) <= span), (gen[1], full[1])
    A1, b1 = later.one_sided()
    for p in feasible_samples(rng, A1.toarray(), b1, later.lo, later.hi, [x1], count=100):
        for i, obj in enumerate(np.eye(n)):
            assert ge_exact(obj, p, gen[0][i]) and le_exact(obj, p, gen[1][i])


def test_row_generation_starts_where_the_same_objectives_bound(monkeypatch):
    """The LP loads the rows with a nonzero multiplier in the last LPs of the same family,
    not evenly spread rows; another family's LPs leave it to the spread rows."""
    import calib_dsl.lp.bounds as bounds
    from calib_dsl.lp.highs import starting_rows

    m = 300  # x_j <= 1 + k / m for row k = 3 q + j: one row per column binds (k = j)
    A = np.zeros((m, 3))
    A[np.arange(m), np.arange(m) % 3] = 1.0
    b = 1.0 + np.arange(m) / m
    rel = LinearRelaxation(rows_of(A), b, np.full(3, -5.0), np.full(3, 5.0), 3,
                           keys=np.arange(m), family="f", col_keys=np.arange(3))
    loaded = []
    real_load = bounds.load
    monkeypatch.setattr(bounds, "load", lambda r, rows=None, *a, **k: (
        loaded.append(None if rows is None else np.array(rows)), real_load(r, rows, *a, **k))[1])
    certs = Certificates()
    tall = LPSettings(rows_at_once=4, workers=1)
    first = lp_bounds(rel, np.eye(3), tall, certificates=certs)
    assert np.array_equal(loaded[-1], starting_rows(rel))
    again = lp_bounds(rel, np.eye(3), tall, certificates=certs)
    assert np.array_equal(loaded[-1], [0, 1, 2])  # the rows that bound x_j from above
    assert np.array_equal(first[1], again[1]) and np.all(again[1] <= 1.0 + 3 / m)
    other = replace(rel, family="g")
    lp_bounds(other, np.eye(3), tall, certificates=certs.copy())
    assert np.array_equal(loaded[-1], starting_rows(rel))
    # another family whose keys mean the same rows (LinearRelaxation.key_space) starts
    # from them; a different key space, or none, does not
    spaced = Certificates()
    lp_bounds(replace(rel, key_space="s"), np.eye(3), tall, certificates=spaced)
    for space, rows in (("s", [0, 1, 2]), ("t", starting_rows(rel)),
                        ("", starting_rows(rel))):
        lp_bounds(replace(rel, family="g", key_space=space), np.eye(3), tall,
                  certificates=spaced.copy())
        assert np.array_equal(loaded[-1], rows), space


def _with_row_generation(rel, objectives, **more):
    return lp_bounds(rel, objectives, LPSettings(rows_at_once=4, **more))


def test_row_generation_finds_a_bounding_row_left_out_at_the_start():
    from calib_dsl.lp.highs import starting_rows

    m = 30
    A = np.full((m, 1), -1.0)  # -x <= 5: bounds x from below only
    b = np.full(m, 5.0)
    A[13, 0], b[13] = 1.0, 2.0  # x <= 2, a row the starting subset leaves out
    rel = rel_of(A, b, np.array([-1e6]), np.array([1e6]))
    assert 13 not in starting_rows(rel)
    lower, upper = _with_row_generation(rel, np.eye(1))
    # certified, with the rounding pad of a box of +- 1e6
    assert -5.01 <= lower[0] <= -5.0 and 2.0 <= upper[0] <= 2.01


@pytest.mark.parametrize("primal_from", [1, 10**6])  # the primal simplex, then the dual
def test_row_generation_on_an_infeasible_tall_lp(primal_from):
    m = 30
    A = np.full((m, 1), 1.0)  # x <= 1 ...
    b = np.full(m, 1.0)
    A[13, 0], b[13] = -1.0, -2.0  # ... and x >= 2 in a row left out at the start
    rel = rel_of(A, b, np.array([-10.0]), np.array([10.0]))
    lower, upper = _with_row_generation(rel, np.eye(1), tall_primal_columns=primal_from)
    # no point to contain: bounds that cross, the proof of infeasibility (the primal simplex,
    # which tall LPs with many columns run, ends there without it: the dual simplex finds it)
    assert lower[0] > upper[0], (lower, upper)


def test_highs_prints_nothing_on_stdout():
    """highspy 1.16 prints a banner on stdout when a process makes its first HiGHS object,
    before output can be turned off: it would spoil `calibc solve --json -`."""
    import subprocess
    import sys

    code = ("from calib_dsl.lp.highs import load; "
            "from calib_dsl.relax.relaxation import LinearRelaxation, Rows; import numpy as np; "
            "rel = LinearRelaxation(Rows.join(np.ones((1, 1)), np.zeros(0, np.int64), "
            "np.zeros(0, np.int64), np.zeros(0), 0), np.ones(1), np.zeros(1), np.ones(1)); "
            "load(rel).run(); load(rel).run(); print('done')")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout == "done\n"


# -- a plain LP (the Chebyshev fit's) ------------------------------------------------------

@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 6), m=st.integers(1, 40))
def test_minimize_agrees_with_scipys_linprog(seed, n, m):
    from calib_dsl.lp.highs import minimize

    rng = np.random.default_rng(seed)
    x_hat = rng.uniform(-1, 1, n)
    A = rng.normal(size=(m, n)) * (rng.random((m, n)) < 0.7) * 10.0 ** rng.integers(-3, 4, n)
    b = A @ x_hat + rng.exponential(0.5, m)
    lo = np.where(rng.random(n) < 0.2, -np.inf, -3.0)
    hi = np.full(n, 3.0)
    cost = rng.normal(size=n)
    x = minimize(LinearRelaxation(rows_of(A), b, lo, hi, n), cost)
    ref = linprog(cost, A_ub=A, b_ub=b, bounds=[(None if not np.isfinite(a) else a, 3.0)
                                                 for a in lo], method="highs")
    if ref.status == 3:  # unbounded below
        assert x is None
        return
    assert ref.status == 0 and x is not None
    assert abs(cost @ x - ref.fun) <= 1e-7 * (1 + abs(ref.fun))
    assert np.all(A @ x <= b + 1e-7 * (1 + np.abs(A) @ np.abs(x)))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 5), m=st.integers(3, 40))
def test_remainder_cost_is_what_the_remainders_add_to_the_bounds(seed, n, m):
    """Certificates.remainder_cost: the kept multipliers certify, on the same rows without
    their slack, bounds narrower by exactly the cost (to rounding), in the unknown's units."""
    rng = np.random.default_rng(seed)
    rel, _ = two_sided_lp(rng, n, m)
    slack = rng.exponential(0.3, m) * (rng.random(m) < 0.7)
    rel.keys, rel.family, rel.col_keys = np.arange(m), "f", np.arange(n)
    rel.scale, rel.slack = rng.uniform(0.5, 2.0, n), slack
    certs = Certificates()
    lp_bounds(rel, np.eye(n), certificates=certs)
    cost = certs.remainder_cost(rel, n)
    assert np.all(cost >= 0)
    tight = replace(rel, b=rel.b - slack, b_lo=rel.b_lo + slack)
    gained = np.zeros(n)
    for (i, sign), (_, y) in certs.y.items():
        c = sign * np.eye(n)[i]
        t = y / rel.scale[i]  # (kept for the unknown p = scale t)
        gained[i] += (certified_max(rel, c, t) - certified_max(tight, c, t)) * rel.scale[i]
    assert np.allclose(gained, cost, rtol=1e-6, atol=1e-9), (gained, cost)
    # nothing is known without the slack, or for another family's relaxation
    assert not np.any(certs.remainder_cost(replace(rel, slack=None), n))
    assert not np.any(certs.remainder_cost(replace(rel, family="g"), n))


def test_a_coefficient_that_is_no_number_bounds_nothing():
    """A NaN coefficient (an objective or multiplier not computed) gives +inf, never a
    finite bound; a zero coefficient over an unbounded entry still contributes 0."""
    lo, hi = np.array([-1.0, -np.inf]), np.array([1.0, np.inf])
    assert box_max_up(np.array([1.0, np.nan]), np.array([1.0, np.nan]), lo, hi) == np.inf
    assert box_max_up(np.array([np.nan, 0.0]), np.array([1.0, 0.0]), lo, hi) == np.inf
    assert 1.0 <= box_max_up(np.array([1.0, 0.0]), np.array([1.0, 0.0]), lo, hi) <= 1.0 + 1e-8
    rows = box_maxes_up(np.array([[1.0, 0.0], [2.0, np.nan]]),
                        np.array([[1.0, 0.0], [2.0, np.nan]]), lo, hi)
    assert rows[0] <= 1.0 + 1e-8 and rows[1] == np.inf


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(1, 40), st.integers(1, 6), st.integers(-1, 50))
def test_the_row_checks_blocks_give_the_whole_products(seed, m, n, block):
    # any block of rows (one, more than the rows, none at all) gives the whole matrix's
    # products bit for bit, and so the same violated rows
    from calib_dsl.lp.highs import RowCheck

    rng = np.random.default_rng(seed)
    full = rng.normal(size=(m, n)) * (rng.random((m, n)) < 0.5) * 10.0 ** rng.integers(-4, 5)
    full[rng.random(m) < 0.2] = 0.0  # (empty rows among them)
    A = sparse.csr_matrix(full)
    x = rng.normal(size=n)
    rel = LinearRelaxation(Rows(A.data, A.indices, A.indptr, A.shape), full @ x - 0.1, -np.ones(n),
                           np.ones(n))
    check = RowCheck(rel, m, block)
    assert (check.whole is not None) == (max(1, block) >= m)  # (one block: made once)
    ax, scale = check.products(x)
    assert np.array_equal(ax, A @ x)
    assert np.array_equal(scale, abs(A) @ np.abs(x))
    inside = rng.permutation(m)[: int(rng.integers(0, m + 1))]
    assert np.array_equal(RowCheck(rel, m, block).violated(x, inside),
                          RowCheck(rel, m, m + 1).violated(x, inside))
