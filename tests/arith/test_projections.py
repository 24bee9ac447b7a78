"""Forward and backward projections of every primitive: soundness on random solution points
(exact values via Fraction / mpmath), optimality (the bounds are attained), the paper's
Example 1 and Figure 4, periodic corner cases, empties/infinities, vectorization, DAG folding."""

from __future__ import annotations

import itertools
import math
from fractions import Fraction

import mpmath  # exact references (a dev dependency)
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calib_dsl.arith import interval as iv
from calib_dsl.arith.projections import backward, forward

ENCLOSE_ULPS = 1  # references are exact (mpmath): one float outward
mp = mpmath.mpf
INF = math.inf
A = np.asarray

UNARY = ["neg", "sqr", "sqrt", "exp", "log", "sin", "cos", "tan", "abs", "pow"]
BINARY = ["add", "sub", "mul", "div", "atan2"]
ALL_OPS = UNARY + BINARY + ["rotu", "rotv"]


def I(lo: float, hi: float) -> tuple[np.ndarray, np.ndarray]:  # noqa: E743
    return A([float(lo)]), A([float(hi)])


def one(x) -> tuple[float, float]:
    return float(x[0][0]), float(x[1][0])


def nxt(x: float, n: int = 1, toward: float = INF) -> float:
    with np.errstate(over="ignore"):
        for _ in range(n):
            x = float(np.nextafter(x, toward))
    return x


# -- exact reference values -----------------------------------------------------------------

def exact(op: str, pts: list[float], n: float | None = None):
    """The exact value of op at float points: a Fraction for the rational ops, else an mpf
    at 300 bits (plenty: the arguments are floats of modest exponent)."""
    q = [Fraction(p) for p in pts]
    if op == "neg":
        return -q[0]
    if op == "sqr":
        return q[0] * q[0]
    if op == "abs":
        return abs(q[0])
    if op == "pow":
        assert n is not None
        return q[0] ** int(n)
    if op in ("add", "sub", "mul", "div"):
        return {"add": q[0] + q[1], "sub": q[0] - q[1], "mul": q[0] * q[1],
                "div": q[0] / q[1] if q[1] else None}[op]
    m = [mp(p) for p in pts]
    with mpmath.workprec(300):
        if op == "atan2":
            t = mpmath.atan2(m[0], m[1])
            return mpmath.pi if t == -mpmath.pi else t  # -0.0 is 0: the angle is pi
        if op in ("rotu", "rotv"):
            c, s = mpmath.cos(m[0]), mpmath.sin(m[0])
            return m[1] * c - m[2] * s if op == "rotu" else m[1] * s + m[2] * c
        return getattr(mpmath, {"sqrt": "sqrt", "exp": "exp", "log": "log", "sin": "sin",
                                "cos": "cos", "tan": "tan"}[op])(m[0])


def inside(lo: float, hi: float, v) -> bool:
    if isinstance(v, Fraction):
        return (lo == -INF or Fraction(lo) <= v) and (hi == INF or v <= Fraction(hi))
    return mp(lo) <= v <= mp(hi)


def enclose(v) -> tuple[float, float]:
    """A float interval holding the exact value v (one ulp each side of the nearest float)."""
    f = float(v)
    return nxt(f, ENCLOSE_ULPS, -INF), nxt(f, ENCLOSE_ULPS, INF)


# -- random solution points and boxes around them -------------------------------------------

def draw_point(rng: np.random.Generator, op: str) -> float:
    k = rng.integers(0, 6)
    if k == 0:
        x = float(rng.integers(-4, 5))
    elif k == 1 and op in ("sin", "cos", "tan", "atan2", "rotu", "rotv"):
        x = float(rng.integers(-8, 9)) * np.pi / 2 * (1 + rng.choice([0, 1e-16, -1e-16, 1e-9]))
    elif k == 2 and op in ("sin", "cos", "tan"):
        x = float(rng.normal() * 10.0 ** rng.uniform(2, 12))
    else:
        x = float(rng.normal() * 10.0 ** rng.uniform(-6, 3))
    if op == "exp":
        x = float(np.clip(x, -700, 700))
    if op in ("sqrt", "log"):
        x = abs(x) if x != 0 or op == "sqrt" else 1.0
    return x


def widen(rng: np.random.Generator, lo: float, hi: float, scale: float) -> tuple[float, float]:
    """[lo - r1, hi + r2] with r's drawn among 0, tiny, relative, large and infinite."""
    def r() -> float:
        k = rng.integers(0, 6)
        if k == 0:
            return 0.0
        if k == 1:
            return INF if rng.random() < 0.5 else 0.0
        return float(abs(rng.normal()) * max(scale, 1e-300) * 10.0 ** rng.uniform(-12, 1))
    return lo - r(), hi + r()


def solution_case(rng: np.random.Generator, op: str):
    """A random point satisfying op, a box around it: (out box, arg boxes, point, z, n)."""
    n = None
    arity = 1 if op in UNARY else 2 if op in BINARY else 3
    while True:
        pts = [draw_point(rng, op) for _ in range(arity)]
        if op == "pow":
            n = float(rng.choice([-5, -4, -3, -2, -1, 2, 3, 4, 5, 6, 7]))
            pts[0] = float(np.clip(pts[0], -1e4, 1e4))
            if n < 0 and pts[0] == 0:
                continue
        if op == "div" and pts[1] == 0:
            continue
        if op == "atan2" and pts[0] == 0 and pts[1] == 0:
            continue
        z = exact(op, pts, n)
        if z is None:
            continue
        try:
            zl, zh = enclose(z)
        except OverflowError:
            continue
        if not (math.isfinite(zl) and math.isfinite(zh)):
            continue
        break
    boxes = [widen(rng, p, p, abs(p) + 1) for p in pts]
    zbox = widen(rng, zl, zh, abs(zl) + 1)
    return zbox, boxes, pts, z, n


# 6 examples here; bench/checks/test_soundness_full.py runs 60
@pytest.mark.parametrize("op", ALL_OPS)
@settings(max_examples=6, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_sound(op: str, seed: int) -> None:
    """forward contains f(point); backward keeps every coordinate of the point (vectorized:
    many cases per call, so elementwise independence is exercised too)."""
    rng = np.random.default_rng(seed)
    cases = [solution_case(rng, op) for _ in range(25)]
    k = len(cases[0][1])
    out = (A([c[0][0] for c in cases]), A([c[0][1] for c in cases]))
    args = [(A([c[1][j][0] for c in cases]), A([c[1][j][1] for c in cases])) for j in range(k)]
    param = A([c[4] for c in cases]) if op == "pow" else None
    flo, fhi = forward(op, args, param)
    res = backward(op, out, args, param)
    for i, (_, _, pts, z, _) in enumerate(cases):
        assert inside(flo[i], fhi[i], z), (op, [(a[0][i], a[1][i]) for a in args], pts, z)
        for j in range(k):
            assert res[j][0][i] <= pts[j] <= res[j][1][i], (
                op, j, (out[0][i], out[1][i]), [(a[0][i], a[1][i]) for a in args], pts,
                (res[j][0][i], res[j][1][i]))
            assert args[j][0][i] <= res[j][0][i] and res[j][1][i] <= args[j][1][i]


@pytest.mark.parametrize("op", ["add", "mul", "div", "sqr", "sin", "cos", "atan2", "pow",
                                "rotu"])
@settings(max_examples=3, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_sound_large_arrays(op: str, seed: int) -> None:
    """As test_sound, with arrays long enough for the arithmetic (not nextafter) rounding."""
    rng = np.random.default_rng(seed)
    cases = [solution_case(rng, op) for _ in range(300)]
    k = len(cases[0][1])
    out = (A([c[0][0] for c in cases]), A([c[0][1] for c in cases]))
    args = [(A([c[1][j][0] for c in cases]), A([c[1][j][1] for c in cases])) for j in range(k)]
    param = A([c[4] for c in cases]) if op == "pow" else None
    flo, fhi = forward(op, args, param)
    res = backward(op, out, args, param)
    for i, (_, _, pts, z, _) in enumerate(cases):
        assert inside(flo[i], fhi[i], z)
        for j in range(k):
            assert res[j][0][i] <= pts[j] <= res[j][1][i], (op, i, j)


# -- optimality: the projection's bounds are attained ---------------------------------------

def _dist(v, lo: float, hi: float) -> float:
    if isinstance(v, Fraction):
        v = mp(v.numerator) / mp(v.denominator)
    if mpmath.isinf(v):
        return 0.0 if (v > 0 and hi == INF) or (v < 0 and lo == -INF) else INF
    if v < mp(lo):
        return float(mp(lo) - v)
    if v > mp(hi):
        return float(v - mp(hi))
    return 0.0


def random_box(rng: np.random.Generator, op: str) -> tuple[float, float]:
    c = draw_point(rng, op)
    w = abs(rng.normal()) * 10.0 ** rng.uniform(-3, 1) * (1 + abs(c))
    lo, hi = c - w * rng.random(), c + w * rng.random()
    if op in ("sqrt", "log"):
        lo = max(lo, 0.0)
    return lo, hi


@pytest.mark.parametrize("op", ["neg", "sqr", "sqrt", "exp", "log", "sin", "cos", "tan",
                                "abs", "pow"])
@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_unary_optimal(op: str, seed: int) -> None:
    """Each finite bound L of the projection satisfies f(L) in z (up to rounding slack):
    nothing feasible-looking was left out and nothing infeasible kept at the ends."""
    rng = np.random.default_rng(seed)
    x = random_box(rng, op)
    n = float(rng.choice([-3, -2, 2, 3, 4, 5])) if op == "pow" else None
    if rng.random() < 0.5:  # z from the image of a sub-box, so the projection is non-empty
        s = sorted(rng.uniform(x[0], x[1], 2))
        fl, fh = one(forward(op, [I(s[0], s[1])], A([n]) if n else None))
        z = (fl, fh)
    else:
        z = random_box(rng, "exp" if op in ("exp", "sqr", "abs", "sqrt") else op)
    param = A([n]) if n else None
    (lo, hi), = [one(r) for r in backward(op, I(*z), [I(*x)], param)]
    if lo > hi:
        return
    for b in (lo, hi):
        if not math.isfinite(b) or (op in ("pow",) and n is not None and n < 0 and b == 0):
            continue
        v = exact(op, [b], n)
        scale = max(1.0, abs(float(v)) if not isinstance(v, Fraction) else abs(float(v)))
        tol = 1e-11 * scale * (1 + abs(b))  # margins scale with |b| (and f's slope)
        if op == "tan":
            tol *= 1 + float(v) ** 2  # tan's slope
        assert _dist(v, *z) <= tol, (op, x, z, n, (lo, hi), b, v)


@pytest.mark.parametrize("op", ["add", "sub", "mul", "div"])
@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_binary_optimal(op: str, seed: int) -> None:
    """Each finite bound of x's projection, with some y in y's box, lands in z (checked with
    the exact extreme values of f(L, y) over y, f being monotone in y)."""
    rng = np.random.default_rng(seed)
    x, y, z = random_box(rng, op), random_box(rng, op), random_box(rng, op)
    if rng.random() < 0.6:  # z from a sub-box's image
        sx = sorted(rng.uniform(*x, 2))
        sy = sorted(rng.uniform(*y, 2))
        z = one(forward(op, [I(*sx), I(*sy)]))
    rx, ry = (one(r) for r in backward(op, I(*z), [I(*x), I(*y)]))
    if rx[0] > rx[1]:
        assert ry[0] > ry[1]
        return
    for j, (r, other) in enumerate(((rx, y), (ry, x))):
        for b in r:
            if not math.isfinite(b):
                continue
            vals = []
            for o in other:
                pts = [b, o] if j == 0 else [o, b]
                v = exact(op, pts)
                if v is not None:
                    vals.append(mp(v.numerator) / mp(v.denominator))
            if op == "div" and ((j == 0 and other[0] <= 0 <= other[1]) or j == 1):
                continue  # f(L, .) not monotone over y (pole): covered by the tests below
            vlo, vhi = min(vals), max(vals)
            scale = 1e-12 * (1 + abs(float(vlo)) + abs(float(vhi)))
            gap = max(0.0, float(mp(z[0]) - vhi), float(vlo - mp(z[1])))
            assert gap <= scale, (op, x, y, z, rx, ry, j, b)


def test_mul_div_with_zero() -> None:
    # z = x * y: 0 in z and in y -> x unconstrained
    rx, ry = (one(r) for r in backward("mul", I(-1, 1), [I(-5, 7), I(-1, 2)]))
    assert rx == (-5, 7)
    # two pieces of z / y, cut by x before the hull: x would have to be <= -1 or >= 1
    rx, ry = (one(r) for r in backward("mul", I(1, 2), [I(-0.5, 0.5), I(-1, 1)]))
    assert rx[0] > rx[1] and ry[0] > ry[1]
    rx, _ = (one(r) for r in backward("mul", I(1, 2), [I(-0.5, 4), I(-1, 1)]))
    assert rx[0] <= 1 and rx[0] >= nxt(1.0, 1, -INF) and rx[1] == 4
    # z = x / y
    rx, ry = (one(r) for r in backward("div", I(2, 3), [I(-10, 10), I(1, 2)]))
    assert rx[0] <= 2 and rx[0] >= nxt(2.0, 1, -INF) and rx[1] >= 6 and rx[1] <= nxt(6.0)
    rx, ry = (one(r) for r in backward("div", I(-1, 1), [I(0, 0), I(-3, 3)]))
    assert ry == (-3, 3)  # x = 0 and z = 0: any y != 0
    rx, ry = (one(r) for r in backward("div", I(1, 2), [I(1, 1), I(-3, 3)]))
    assert ry[0] >= nxt(0.5, 1, -INF) and ry[0] <= 0.5 and ry[1] >= 1 and ry[1] <= nxt(1.0)
    assert one(forward("div", [I(1, 1), I(0, 0)]))[0] == INF  # division by exactly 0: empty


def test_even_odd_powers() -> None:
    p = A([4.0])
    assert one(backward("pow", I(16, 81), [I(-10, 2)], p)[0])[0] <= -2
    lo, hi = one(backward("pow", I(16, 81), [I(-10, 2)], p)[0])
    assert lo >= -3 - 1e-12 and lo <= -3 and hi == 2
    lo, hi = one(backward("pow", I(16, 81), [I(-1, 1)], p)[0])
    assert lo > hi  # both branches miss x
    lo, hi = one(backward("pow", I(-27, 8), [I(-10, 10)], A([3.0]))[0])
    assert abs(lo + 3) < 1e-12 and abs(hi - 2) < 1e-12
    lo, hi = one(backward("pow", I(-27, -8), [I(-10, 10)], A([-3.0]))[0])
    assert abs(lo + 0.5) < 1e-12 and abs(hi + 1 / 3) < 1e-12 and lo <= -0.5 and hi >= -1 / 3
    lo, hi = one(backward("pow", I(8, 27), [I(-10, 0)], A([-3.0]))[0])
    assert lo > hi  # x**-3 > 0 needs x > 0
    lo, hi = one(backward("pow", I(-1 / 8, -1 / 27), [I(-10, 10)], A([-3.0]))[0])
    assert abs(lo + 3) < 1e-12 and abs(hi + 2) < 1e-12
    lo, hi = one(backward("sqr", I(4, 9), [I(-10, 2.5)])[0])
    assert lo <= -3 and lo >= nxt(-3.0, 1, -INF) and hi == 2.5
    lo, hi = one(backward("abs", I(4, 9), [I(-1, 5)])[0])
    assert (lo, hi) == (4, 5)
    lo, hi = one(backward("sqrt", I(-1, 3), [I(-5, 5)])[0])
    assert lo == 0 and hi == 5
    # per-element exponents in one call
    r = backward("pow", (A([4.0, -8.0]), A([9.0, 27.0])), [(A([-5.0, -5.0]), A([5.0, 5.0]))],
                 A([2.0, 3.0]))[0]
    assert abs(r[0][0] + 3) < 1e-12 and abs(r[1][0] - 3) < 1e-12
    assert abs(r[0][1] + 2) < 1e-12 and abs(r[1][1] - 3) < 1e-12


# -- the paper's examples -------------------------------------------------------------------

def contract(op: str, out, args, param=None):
    """forward then backward, as one application of the primitive's contractor."""
    f = forward(op, args, param)
    out = iv.intersect(out, f)
    return out, backward(op, out, args, param)


def test_example_1() -> None:
    """x3 = x2 - x1: [a] gives [1,2]x[2,5]x[1,3], [b] gives [4,5]x[5,6]x[1,2] (bounds that
    come out of an addition may be an ulp or two wider: round to nearest, then outward)."""
    def close(got, lo, hi):
        assert got[0] <= lo and got[0] >= nxt(lo, 2, -INF), (got, lo, hi)
        assert got[1] >= hi and got[1] <= nxt(hi, 2, INF), (got, lo, hi)

    x3, (x2, x1) = contract("sub", I(1, 3), [I(1, 6), I(1, 2)])
    close(one(x1), 1, 2)
    close(one(x2), 2, 5)
    close(one(x3), 1, 3)
    x3, (x2, x1) = contract("sub", I(1, 3), [I(2, 6), I(4, 7)])
    close(one(x1), 4, 5)
    close(one(x2), 5, 6)
    close(one(x3), 1, 2)


def test_figure_4_sine() -> None:
    """y = sin(x): the box misses the curve; contraction along one axis; along the other;
    along both; none."""
    def sin_box(x, y):
        y2, (x2,) = contract("sin", I(*y), [I(*x)])
        return one(x2), one(y2)

    x, y = sin_box((0.5, 1.0), (-0.8, -0.5))  # empty
    assert x[0] > x[1] and y[0] > y[1]
    x, y = sin_box((0.0, math.pi), (0.5, 0.7))  # x only
    assert y == (0.5, 0.7)
    assert abs(x[0] - math.asin(0.5)) < 1e-13 and abs(x[1] - (math.pi - math.asin(0.5))) < 1e-13
    assert x[0] <= math.asin(0.5) and x[1] >= math.pi - math.asin(0.5)
    x, y = sin_box((0.1, 0.5), (-1.0, 1.0))  # y only
    assert x == (0.1, 0.5)
    assert y[0] <= math.sin(0.1) and abs(y[0] - math.sin(0.1)) < 4e-15
    assert y[1] >= math.sin(0.5) and abs(y[1] - math.sin(0.5)) < 4e-15
    x, y = sin_box((0.0, 1.0), (0.5, 2.0))  # both
    assert abs(x[0] - math.asin(0.5)) < 1e-13 and x[1] == 1.0
    assert y[0] == 0.5 and abs(y[1] - math.sin(1.0)) < 4e-15
    x, y = sin_box((0.0, 2.0), (0.0, 1.0))  # none
    assert x == (0.0, 2.0) and y == (0.0, 1.0)


def test_sine_periodic_cases() -> None:
    a5 = math.asin(0.5)
    # hull of a union of branches
    x = one(backward("sin", I(0.5, 0.6), [I(0, 10)])[0])
    assert abs(x[0] - a5) < 1e-13 and abs(x[1] - (3 * math.pi - math.asin(0.5) - 0.0)) < 1e-3
    assert abs(x[1] - (2 * math.pi + math.pi - a5)) < 1e-12
    # wider than 2 pi, trimmed at both ends
    x = one(backward("sin", I(0.9, 1.0), [I(-0.5, 19.5)])[0])
    assert abs(x[0] - math.asin(0.9)) < 1e-12
    assert abs(x[1] - (4 * math.pi + math.pi - math.asin(0.9))) < 1e-12
    # infinite x: no contraction on x, y clipped to [-1, 1]
    y, (x2,) = contract("sin", I(0.5, 2.0), [I(-INF, INF)])
    assert one(x2) == (-INF, INF) and one(y) == (0.5, 1.0)
    y, (x2,) = contract("sin", I(0.5, 2.0), [I(-INF, 0.0)])
    assert one(x2)[0] == -INF and abs(one(x2)[1] - (-2 * math.pi + math.pi - a5)) < 1e-12
    # y entirely outside [-1, 1]
    assert one(backward("sin", I(1.5, 2.0), [I(-INF, INF)])[0])[0] == INF
    # cos and tan
    x = one(backward("cos", I(-0.2, 0.3), [I(0, 10)])[0])
    assert abs(x[0] - math.acos(0.3)) < 1e-12
    assert abs(x[1] - (2 * math.pi + math.acos(-0.2))) < 1e-12
    x = one(backward("tan", I(1, 2), [I(-3, 3)])[0])
    assert abs(x[0] - (math.atan(1) - math.pi)) < 1e-12 and abs(x[1] - math.atan(2)) < 1e-12
    x = one(backward("tan", I(-INF, INF), [I(-3, 3)])[0])
    assert x == (-3, 3)


def test_sine_near_extrema_and_large() -> None:
    one_m = nxt(1.0, 1, -INF)
    hp = math.pi / 2  # below pi/2: sin(hp) is 1 (rounded); exactly 1 - 1.9e-33
    x = one(backward("sin", I(one_m, 1.0), [I(0, 3)])[0])
    assert x[0] <= hp <= x[1] and x[1] - x[0] < 1e-6
    # z excludes 1: two tiny branches around pi/2, hull
    z = (1 - 1e-10, 1 - 5e-11)
    x = one(backward("sin", I(*z), [I(0, 3)])[0])
    assert x[0] < hp - 1e-5 and x[1] > hp + 1e-5 and x[1] - x[0] < 3e-5
    with mpmath.workprec(200):
        for b in x:
            assert z[0] - 1e-15 <= float(mpmath.sin(mp(b))) <= z[1] + 1e-15
    # z = [-1, -1]: only the minima (the float 3pi/2 does not reach -1 exactly)
    x = one(backward("sin", I(-1, -1), [I(0, 10)])[0])
    assert x[0] <= 3 * math.pi / 2 and x[1] >= 3 * math.pi / 2 and x[1] - x[0] < 1e-6
    # large |x|: sound (every sampled solution kept) and still contracting at 1e8
    a = 1e8
    x = one(backward("sin", I(0.3, 0.4), [I(a, a + 10)])[0])
    assert x[0] > a and x[1] < a + 10
    grid = np.linspace(a, a + 10, 20001)
    with mpmath.workprec(200):
        for g in grid[::7]:
            if 0.3 <= float(mpmath.sin(mp(float(g)))) <= 0.4:
                assert x[0] <= g <= x[1]


@settings(max_examples=300, deadline=None)
@given(k=st.integers(-10**9, 10**9), which=st.sampled_from(["sin", "cos"]),
       off=st.sampled_from([0.0, 1e-16, -1e-16, 1e-8, -1e-8]), wz=st.sampled_from([0, 1e-17,
                                                                                   1e-9]))
def test_periodic_at_extrema_sound(k: int, which: str, off: float, wz: float) -> None:
    """Points at (or next to) the float nearest an extremum, up to |x| ~ 1.6e9: the tightest
    z around f(x) still keeps x."""
    x = (k * math.pi / 2) * (1 + off) + off
    with mpmath.workprec(300):
        v = getattr(mpmath, which)(mp(x))
    zl, zh = enclose(v)
    zl, zh = zl - wz, zh + wz
    lo, hi = one(backward(which, I(zl, zh), [I(x - 1.0, x + 7.0)])[0])
    assert lo <= x <= hi


# -- atan2 ----------------------------------------------------------------------------------

def _grid_projection(z, y, x, n: int = 401):
    """Inner approximation of atan2's projections: points of a box grid whose angle is in z,
    and points of a polar grid (angles in z, radii down to 1e-9) that lie in the box."""
    gy, gx = np.meshgrid(np.linspace(y[0], y[1], n), np.linspace(x[0], x[1], n), indexing="ij")
    t = np.arctan2(gy + 0.0, gx + 0.0)
    ok = (t >= z[0]) & (t <= z[1]) & ~((gx == 0) & (gy == 0))
    ys, xs = [gy[ok]], [gx[ok]]
    tt, rr = np.meshgrid(np.linspace(z[0], z[1], 301), np.geomspace(1e-9, 5, 400))
    py, px = rr * np.sin(tt), rr * np.cos(tt)
    ok = (py >= y[0]) & (py <= y[1]) & (px >= x[0]) & (px <= x[1])
    ys.append(py[ok])
    xs.append(px[ok])
    ay, ax = np.concatenate(ys), np.concatenate(xs)
    if ay.size == 0:
        return None
    return (ay.min(), ay.max()), (ax.min(), ax.max())


# 20 examples here; bench/checks/test_soundness_full.py runs 200
@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_atan2_near_optimal(seed: int) -> None:
    """atan2's projections hold every grid solution and exceed the grid hull by at most
    about a grid step (scaled by how fast the angle moves)."""
    rng = np.random.default_rng(seed)
    y = tuple(sorted(rng.uniform(-2, 2, 2)))
    x = tuple(sorted(rng.uniform(-2, 2, 2)))
    c = rng.uniform(-math.pi, math.pi)
    w = rng.uniform(0, 1.5)
    z = (max(c - w, -math.pi), min(c + w, math.pi))
    if rng.random() < 0.2:
        z = (rng.uniform(1.7, 3.1), math.pi)  # touches pi
    ry, rx = (one(r) for r in backward("atan2", I(*z), [I(*y), I(*x)]))
    g = _grid_projection(z, y, x)
    if g is None:
        return
    (gy0, gy1), (gx0, gx1) = g
    assert ry[0] <= gy0 and gy1 <= ry[1] and rx[0] <= gx0 and gx1 <= rx[1]
    step = 4 * max(y[1] - y[0], x[1] - x[0]) / 400 + 1e-9
    zz = max(z[0], -3.0), min(z[1], 3.0)  # the left half's tan hull is the documented gap
    if not (zz[0] <= -math.pi / 2 and zz[1] >= math.pi / 2):
        assert ry[0] >= gy0 - step and ry[1] <= gy1 + step, (z, y, x, ry, g)
        assert rx[0] >= gx0 - step and rx[1] <= gx1 + step, (z, y, x, rx, g)


def test_atan2_cases() -> None:
    # the angle pi/4 cuts the box [-1,2] x [-1,1] (x, y) to 0 <= x = y <= 1
    ry, rx = (one(r) for r in backward("atan2", I(math.pi / 4, math.pi / 4),
                                       [I(-1, 1), I(-1, 2)]))
    assert abs(ry[0]) < 1e-12 and abs(ry[1] - 1) < 1e-12 and abs(rx[0]) < 1e-12
    assert abs(rx[1] - 1) < 1e-12
    # angles near pi on the left half-plane: y small, x < 0
    ry, rx = (one(r) for r in backward("atan2", I(3.0, math.pi), [I(-1, 1), I(-2, 2)]))
    assert rx[1] <= 0 + 1e-12 and ry[0] >= -1e-12 and ry[1] <= 2 * math.tan(math.pi - 3) + 1e-9
    # empty: angle in the first quadrant, box in the third
    ry, rx = (one(r) for r in backward("atan2", I(0.1, 1.0), [I(-2, -1), I(-2, -1)]))
    assert ry[0] > ry[1] and rx[0] > rx[1]
    # forward by quadrant
    lo, hi = one(forward("atan2", [I(1, 2), I(1, 2)]))
    assert lo <= math.atan2(1, 2) and hi >= math.atan2(2, 1) and hi - lo < math.pi / 2


# -- empties, infinities, NaN, vectorization, DAG folding -----------------------------------

SPECIAL = [(-INF, INF), (-INF, -1.0), (-INF, 0.0), (0.0, INF), (2.0, INF), (0.0, 0.0),
           (-0.0, 0.0), (-1.0, 1.0), (1.0, 2.0), (-3.0, -2.0), (INF, -INF), (3.0, 2.0),
           (INF, INF), (-INF, -INF), (1e300, 1e308), (-1e-310, 1e-310)]


def _special_args(arity: int):
    combos = list(itertools.product(range(len(SPECIAL)), repeat=arity))
    cols = []
    for j in range(arity):
        cols.append((A([SPECIAL[c[j]][0] for c in combos]), A([SPECIAL[c[j]][1] for c in combos])))
    return combos, cols


@pytest.mark.parametrize("op", ALL_OPS)
def test_special_inputs(op: str) -> None:
    """No NaN, canonical empties, results inside the arguments, empty in -> empty out."""
    arity = 1 if op in UNARY else 2 if op in BINARY else 3
    combos, cols = _special_args(arity)
    param = np.full(len(combos), -3.0 if op == "pow" else 0.0) if op == "pow" else None
    with np.errstate(all="raise"):  # the entry points must not leak floating-point warnings
        f = forward(op, cols, param)
        for out in SPECIAL[:8] + SPECIAL[10:12]:
            o = (np.full(len(combos), out[0]), np.full(len(combos), out[1]))
            res = backward(op, o, cols, param)
            for (lo, hi), (alo, ahi) in zip(res, cols, strict=True):
                assert not np.isnan(lo).any() and not np.isnan(hi).any()
                e = lo > hi
                assert (lo[e] == INF).all() and (hi[e] == -INF).all()
                assert (lo[~e] >= alo[~e]).all() and (hi[~e] <= ahi[~e]).all()
            for j, c in enumerate(combos):
                if any(SPECIAL[k][0] > SPECIAL[k][1] or SPECIAL[k] in ((INF, INF), (-INF, -INF))
                       for k in c) or out[0] > out[1]:
                    assert all(r[0][j] == INF and r[1][j] == -INF for r in res), (op, c, out)
    assert not np.isnan(f[0]).any() and not np.isnan(f[1]).any()
    for j, c in enumerate(combos):
        if any(SPECIAL[k][0] > SPECIAL[k][1] for k in c):
            assert f[0][j] == INF and f[1][j] == -INF


@pytest.mark.parametrize("op", ALL_OPS)
@pytest.mark.parametrize("n", [0, 1, 7])
def test_lengths(op: str, n: int) -> None:
    arity = 1 if op in UNARY else 2 if op in BINARY else 3
    args = [(np.full(n, 0.5), np.full(n, 0.75)) for _ in range(arity)]
    param = np.full(n, 3.0) if op == "pow" else None
    f = forward(op, args, param)
    assert f[0].shape == (n,) and f[1].shape == (n,)
    res = backward(op, f, args, param)
    assert len(res) == arity and all(r[0].shape == (n,) for r in res)
    if n:
        for r, a in zip(res, args, strict=True):  # f(args) is consistent: no contraction
            assert (r[0] <= a[0]).all() and (r[1] >= a[1]).all()


@pytest.mark.parametrize("op", ALL_OPS)
def test_dag_constant_folding(op: str) -> None:
    from calib_dsl.ir.dag import Dag

    d = Dag()
    vals = [0.3, -0.7, 1.1]
    arity = 1 if op in UNARY else 2 if op in BINARY else 3
    args = [d.literal(str(v)) for v in vals[:arity]]
    data = 3 if op == "pow" else None
    node = d.op(op, *args, data=data)
    lo, hi = d.nodes[node].data
    pts = [float(d.nodes[a].data[0]) for a in args]  # the literal's lower float, exact-ish
    v = exact(op, pts, 3.0 if op == "pow" else None)
    assert lo <= hi and hi - lo < 1e-14
    assert lo - 1e-15 <= float(v) <= hi + 1e-15


def test_unknown_op() -> None:
    with pytest.raises(ValueError):
        forward("frobnicate", [I(0, 1)])
    with pytest.raises(ValueError):
        backward("frobnicate", I(0, 1), [I(0, 1)])
