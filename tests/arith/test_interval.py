"""Outward-rounded interval arithmetic: soundness against exact (Fraction / mpmath) values,
tightness (the bounds are the exact ones up to the stated ulps), 0*inf, empties, no NaN."""

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

A = np.asarray
INF = math.inf
SPECIAL = [-INF, -1e300, -2.5, -1.0, -1e-310, -0.0, 0.0, 1e-310, 0.5, 1.0, 3.0, 1e300, INF]


def nxt(x: float, n: int = 1, toward: float = INF) -> float:
    with np.errstate(over="ignore"):
        for _ in range(n):
            x = float(np.nextafter(x, toward))
    return x


def rand_values(rng: np.random.Generator, n: int) -> np.ndarray:
    """Floats of mixed scales and signs, with exact zeros and small integers."""
    kind = rng.integers(0, 5, n)
    mag = 10.0 ** rng.uniform(-8, 8, n)
    v = np.where(kind == 0, mag, rng.normal(size=n) * 10.0 ** rng.integers(-3, 4, n))
    v = np.where(kind == 1, rng.integers(-4, 5, n).astype(float), v)
    v = np.where(kind == 2, 0.0, v)
    return v * rng.choice([-1.0, 1.0], n)


def rand_boxes(rng: np.random.Generator, n: int, inf_rate: float = 0.1):
    """Random intervals (some infinite bounds, some points) and a point inside each."""
    a, b = rand_values(rng, n), rand_values(rng, n)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    pt = rng.random(n) < 0.2
    hi = np.where(pt, lo, hi)
    t = rng.random(n)
    x = np.clip(lo + t * (hi - lo), lo, hi)
    x = np.where(rng.random(n) < 0.15, lo, np.where(rng.random(n) < 0.15, hi, x))
    lo = np.where(rng.random(n) < inf_rate, -INF, lo)
    hi = np.where(rng.random(n) < inf_rate, INF, hi)
    return (lo, hi), x


def frac_in(lo: float, hi: float, q: Fraction) -> bool:
    return (lo == -INF or Fraction(lo) <= q) and (hi == INF or q <= Fraction(hi))


EXACT = {
    "add": lambda a, b: a + b,
    "sub": lambda a, b: a - b,
    "mul": lambda a, b: a * b,
    "div": lambda a, b: a / b,
}
RAW = {"add": iv.add, "sub": iv.sub, "mul": iv.mul, "div": iv.div}


# -- constants and rounding -----------------------------------------------------------------

def test_pi_enclosure() -> None:
    with mpmath.workprec(200):
        pi = mpmath.pi
        assert mpmath.mpf(iv.PI_LO) < pi < mpmath.mpf(iv.PI_HI)
        assert mpmath.mpf(iv.HALF_PI_LO) < pi / 2 < mpmath.mpf(iv.HALF_PI_HI)
        assert mpmath.mpf(iv.TWO_PI_LO) < 2 * pi < mpmath.mpf(iv.TWO_PI_HI)
    assert iv.PI_HI == np.nextafter(np.pi, INF)


def test_down_up() -> None:
    x = A([-INF, -1.0, 0.0, 1.0, INF])
    d, u = iv.down(x), iv.up(x)
    assert d[0] == -INF and d[4] == INF and u[0] == -INF and u[4] == INF
    assert d[1] == np.nextafter(-1.0, -INF) and u[3] == np.nextafter(1.0, INF)
    assert d[2] < 0 < u[2]
    assert iv.down(A([])).shape == (0,) and iv.up(A([2.0]))[0] > 2.0
    # the arithmetic's own rounding maps an overflowed bound to the largest finite float
    assert iv.dn1(A([INF]))[0] == iv.MAX and iv.up1(A([-INF]))[0] == -iv.MAX


def test_lib_margin_covers_ulps() -> None:
    y = A([1.0, -3.0, 1e-300, 1e-320, 0.0, 1e300])
    lo, hi = iv.lib_lo(y), iv.lib_hi(y)
    for v, a, b in zip(y, lo, hi, strict=True):
        assert a <= nxt(v, 4, -INF) and b >= nxt(v, 4, INF)
    assert iv.lib_lo(A([INF]))[0] <= iv.MAX and iv.lib_hi(A([-INF]))[0] >= -iv.MAX


# -- arithmetic soundness and tightness -----------------------------------------------------

@pytest.mark.parametrize("op", ["add", "sub", "mul", "div"])
@settings(max_examples=300, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_arith_sound(op: str, seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = 40
    x, px = rand_boxes(rng, n)
    y, py = rand_boxes(rng, n)
    with iv.quiet():
        lo, hi = RAW[op](x, y)
    assert not np.isnan(lo).any() and not np.isnan(hi).any()
    for i in range(n):
        if op == "div" and py[i] == 0:
            continue
        z = EXACT[op](Fraction(px[i]), Fraction(py[i]))
        assert frac_in(lo[i], hi[i], z), (op, x[0][i], x[1][i], y[0][i], y[1][i], px[i], py[i])


@pytest.mark.parametrize("op", ["add", "sub", "mul", "div"])
@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_arith_sound_large_arrays(op: str, seed: int) -> None:
    """Arrays above the nextafter/arithmetic switch (iv._SMALL): the arithmetic widening is
    sound and tight, including powers of two, subnormals, zeros and overflow."""
    rng = np.random.default_rng(seed)
    n = 700
    x, px = rand_boxes(rng, n)
    y, py = rand_boxes(rng, n)
    sp = np.array([2.0**-1074, 2.0**-1060, 2.0**-1022, 1.0, 2.0, 4.0, 0.75, iv.MAX, 1e308])
    k = rng.integers(0, sp.size, n)
    pick = rng.random(n) < 0.3
    px = np.where(pick, sp[k] * rng.choice([-1.0, 1.0], n), px)
    x = (np.where(pick, px, x[0]), np.where(pick, px, x[1]))
    assert n > iv._SMALL
    with iv.quiet():
        lo, hi = RAW[op](x, y)
    assert not np.isnan(lo).any() and not np.isnan(hi).any()
    for i in range(n):
        if op == "div" and py[i] == 0:
            continue
        z = EXACT[op](Fraction(px[i]), Fraction(py[i]))
        assert frac_in(lo[i], hi[i], z), (op, x[0][i], x[1][i], y[0][i], y[1][i], px[i], py[i])
    # point inputs: the widening is at most 2 ulps on each side (3 next to the subnormals)
    with iv.quiet():
        lo, hi = RAW[op]((px, px), (py, py))
    for i in range(n):
        if op == "div" and py[i] == 0:
            continue
        z = EXACT[op](Fraction(px[i]), Fraction(py[i]))
        if abs(z) >= Fraction(iv.MAX):
            continue
        f = float(z)
        assert lo[i] >= nxt(f, 3, -INF) and hi[i] <= nxt(f, 3, INF), (op, px[i], py[i])


finite = st.floats(-1e12, 1e12, allow_nan=False, allow_infinity=False)


@pytest.mark.parametrize("op", ["add", "sub", "mul", "div"])
@settings(max_examples=400, deadline=None)
@given(a=finite, b=finite, c=finite, d=finite)
def test_arith_tight(op: str, a: float, b: float, c: float, d: float) -> None:
    """Finite intervals: the result is the exact hull, widened by at most one ulp per side."""
    x, y = (min(a, b), max(a, b)), (min(c, d), max(c, d))
    if op == "div" and y[0] <= 0 <= y[1]:
        return
    corners = [EXACT[op](Fraction(p), Fraction(q)) for p in x for q in y]
    elo, ehi = min(corners), max(corners)
    if max(abs(elo), abs(ehi)) > Fraction(1e300):
        return
    with iv.quiet():
        lo, hi = RAW[op]((A([x[0]]), A([x[1]])), (A([y[0]]), A([y[1]])))
    assert Fraction(lo[0]) <= elo and ehi <= Fraction(hi[0])
    assert lo[0] >= nxt(float(elo), 2, -INF) and hi[0] <= nxt(float(ehi), 2, INF)


def test_mul_zero_times_infinity() -> None:
    def m(x, y):
        with iv.quiet():
            r = iv.mul((A([x[0]]), A([x[1]])), (A([y[0]]), A([y[1]])))
        return float(r[0][0]), float(r[1][0])

    assert m((0, 0), (-INF, 5)) == (0.0, 0.0)
    assert m((0, 0), (-INF, INF)) == (0.0, 0.0)
    assert m((-INF, INF), (0, 0)) == (0.0, 0.0)
    assert m((0, 1), (2, INF)) == (0.0, INF)
    assert m((0, 1), (-INF, -1)) == (-INF, 0.0)
    assert m((-INF, 0), (0, INF)) == (-INF, 0.0)
    assert m((0, 2), (0, 3))[0] == 0.0  # exact zero is not widened
    lo, hi = m((0, 1e-200), (-1e-200, 1))  # ... but an underflowed corner is
    assert lo < 0


def test_div_extended() -> None:
    def dv(x, y):
        with iv.quiet():
            r = iv.div((A([x[0]]), A([x[1]])), (A([y[0]]), A([y[1]])))
        return float(r[0][0]), float(r[1][0])

    assert dv((1, 2), (-1, 1)) == (-INF, INF)
    lo, hi = dv((1, 2), (0, 1))
    assert lo <= 1 and lo >= nxt(1.0, 1, -INF) and hi == INF
    lo, hi = dv((1, 2), (-1, 0))
    assert lo == -INF and hi >= -1 and hi <= nxt(-1.0, 1, INF)
    lo, hi = dv((0, 0), (-1, 1))
    assert lo <= 0 <= hi and hi - lo < 1e-300
    lo, hi = dv((1, 2), (0, 0))
    assert lo > hi  # y = 0 is no solution
    lo, hi = dv((-2, -1), (0, INF))
    assert lo == -INF and hi >= 0 and hi < 1e-300


# -- elementary functions -------------------------------------------------------------------

MP_FUN = {
    "sin": "sin", "cos": "cos", "tan": "tan", "exp": "exp", "log": "log", "sqrt": "sqrt",
    "atan": "atan", "asin": "asin", "acos": "acos",
}
DOMAIN = {"log": (0.0, INF), "sqrt": (0.0, INF), "asin": (-1.0, 1.0), "acos": (-1.0, 1.0)}


def _fun_boxes(rng: np.random.Generator, name: str, n: int):
    lo_d, hi_d = DOMAIN.get(name, (-INF, INF))
    scale = 10.0 ** rng.uniform(-6, 2, n)
    if name in ("sin", "cos", "tan"):
        scale = np.where(rng.random(n) < 0.1, 10.0 ** rng.uniform(2, 15, n), scale)
    if name == "exp":
        scale = np.minimum(scale, 800.0)
    c = rng.normal(size=n) * scale
    # sit exactly on interesting points now and then
    special = rng.choice([0.0, np.pi / 2, -np.pi / 2, np.pi, 1.0, -1.0], n)
    c = np.where(rng.random(n) < 0.2, special, c)
    c = np.clip(c, lo_d, hi_d if hi_d < INF else 1e300)
    if name in ("log", "sqrt"):
        c = np.abs(c)
    w = np.where(rng.random(n) < 0.3, 0.0, np.abs(rng.normal(size=n)) * scale * rng.random(n))
    lo = np.clip(c - w * rng.random(n), lo_d, None)
    hi = np.clip(c + w * rng.random(n), None, hi_d)
    t = rng.random(n)
    x = np.clip(lo + t * (hi - lo), lo, hi)
    x = np.where(rng.random(n) < 0.2, lo, np.where(rng.random(n) < 0.2, hi, x))
    return (lo, hi), x


@pytest.mark.parametrize("name", sorted(MP_FUN))
@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_function_sound(name: str, seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = 30
    box, x = _fun_boxes(rng, name, n)
    with iv.quiet():
        lo, hi = getattr(iv, name)(box)
    assert not np.isnan(lo).any() and not np.isnan(hi).any()
    f = getattr(mpmath, MP_FUN[name])
    with mpmath.workprec(160):
        for i in range(n):
            if name == "log" and x[i] == 0:
                continue
            val = f(mpmath.mpf(float(x[i])))
            assert mpmath.mpf(float(lo[i])) <= val <= mpmath.mpf(float(hi[i])), (
                name, box[0][i], box[1][i], x[i], lo[i], hi[i])


@pytest.mark.parametrize("name", ["exp", "log", "sqrt", "atan", "asin", "acos"])
@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_monotone_tight(name: str, seed: int) -> None:
    """Monotone functions: each bound is within 2**-47 relative (+1e-300) of the exact end."""
    rng = np.random.default_rng(seed)
    box, _ = _fun_boxes(rng, name, 20)
    with iv.quiet():
        lo, hi = getattr(iv, name)(box)
    f = getattr(mpmath, MP_FUN[name])
    dec = name == "acos"
    with mpmath.workprec(160):
        for i in range(20):
            ends = [f(mpmath.mpf(float(box[0][i]))), f(mpmath.mpf(float(box[1][i])))]
            elo, ehi = (ends[1], ends[0]) if dec else (ends[0], ends[1])
            for got, exact in ((lo[i], elo), (hi[i], ehi)):
                if not mpmath.isfinite(exact):
                    continue
                err = abs(mpmath.mpf(float(got)) - exact)
                assert err <= abs(exact) * 2.0**-47 + 1e-300, (name, box[0][i], box[1][i], got)


def _mp_range(mpmath, name: str, a: float, b: float):
    """Exact range of sin/cos over [a, b] for moderate finite a, b (critical points by k)."""
    f = getattr(mpmath, name)
    vals = [f(mpmath.mpf(a)), f(mpmath.mpf(b))]
    pi = mpmath.pi
    phase = pi / 2 if name == "sin" else mpmath.mpf(0)
    k0 = int(mpmath.floor((mpmath.mpf(a) - phase) / pi))
    for k in range(k0, k0 + 4 + int((b - a) / 3.0)):
        t = phase + k * pi
        if mpmath.mpf(a) <= t <= mpmath.mpf(b):
            vals.append(mpmath.mpf(1) if k % 2 == 0 else mpmath.mpf(-1))
    return min(vals), max(vals)


@pytest.mark.parametrize("name", ["sin", "cos"])
@settings(max_examples=200, deadline=None)
@given(a=st.floats(-50, 50), w=st.floats(0, 8))
def test_sincos_range_tight(name: str, a: float, w: float) -> None:
    b = a + w
    with iv.quiet():
        lo, hi = getattr(iv, name)((A([a]), A([b])))
    with mpmath.workprec(160):
        elo, ehi = _mp_range(mpmath, name, a, b)
        assert mpmath.mpf(float(lo[0])) <= elo and ehi <= mpmath.mpf(float(hi[0]))
        # an extremum just outside [a, b] may be counted in: sin there is within 1e-26 of +-1
        assert float(elo) - lo[0] <= 1e-14 and hi[0] - float(ehi) <= 1e-14


@pytest.mark.parametrize("which", ["sin", "cos"])
@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_sincos_extremum_inside_huge(which: str, seed: int) -> None:
    """[a, b] = the floats around a true extremum far from 0 (|x| up to 6e15): the range must
    reach +-1 there, although the float spacing may exceed 0.1 and sin(a) be far from +-1."""
    rng = np.random.default_rng(seed)
    n = 40
    ks = rng.integers(-10**15, 10**15, n) // 10 ** rng.integers(0, 15, n)
    odd = rng.integers(0, 2, n)
    a, b = np.empty(n), np.empty(n)
    with mpmath.workprec(200):
        for i in range(n):
            phase = mpmath.pi / 2 if which == "sin" else 0
            t = phase + (2 * int(ks[i]) + int(odd[i])) * mpmath.pi
            f = float(t)
            a[i] = f if mpmath.mpf(f) <= t else nxt(f, 1, -INF)
            b[i] = f if mpmath.mpf(f) >= t else nxt(f, 1, INF)
    with iv.quiet():
        lo, hi = getattr(iv, which)((a, b))
    assert (lo[odd == 1] == -1.0).all() and (hi[odd == 0] == 1.0).all()


def test_tan_pole_and_branch() -> None:
    with iv.quiet():
        lo, hi = iv.tan((A([1.0, 1.5, -1.0, 1.0, 4.0]), A([2.0, iv.HALF_PI_LO, 1.0, 1.2, 4.5])))
    assert lo[0] == -INF and hi[0] == INF  # holds pi/2
    assert hi[1] > 1e16  # pi/2 float is below pi/2: a huge but finite tan
    assert lo[2] <= np.tan(-1.0) and hi[2] >= np.tan(1.0) and hi[2] < 1.6
    assert lo[3] <= np.tan(1.0) and hi[3] >= np.tan(1.2)
    assert lo[4] <= np.tan(4.0) and hi[4] >= np.tan(4.5) and hi[4] < 5


def test_sincos_infinite_and_huge() -> None:
    with iv.quiet():
        for f in (iv.sin, iv.cos):
            lo, hi = f((A([-INF, 0.0, -INF, 1e300, 1e15]), A([INF, INF, 0.0, 1e300, 1e15])))
            assert lo[:3].tolist() == [-1.0] * 3 and hi[:3].tolist() == [1.0] * 3
            assert (lo >= -1).all() and (hi <= 1).all()
    with mpmath.workprec(2000):  # enough bits to reduce 1e300 modulo 2pi
        for name in ("sin", "cos"):
            pts = (1e300, 1e15, 1e6 + 0.1)
            with iv.quiet():
                lo, hi = getattr(iv, name)((A(pts), A(pts)))
            for i, x in enumerate(pts):
                v = getattr(mpmath, name)(mpmath.mpf(x))
                assert mpmath.mpf(float(lo[i])) <= v <= mpmath.mpf(float(hi[i]))
            assert hi[2] - lo[2] < 1e-14  # 1e6 is still located exactly enough


# -- atan2 (forward) ------------------------------------------------------------------------

@settings(max_examples=300, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_atan2_sound(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = 30
    y, py = rand_boxes(rng, n, inf_rate=0.05)
    x, px = rand_boxes(rng, n, inf_rate=0.05)
    with iv.quiet():
        lo, hi = iv.atan2(y, x)
    assert not np.isnan(lo).any() and not np.isnan(hi).any()
    with mpmath.workprec(160):
        for i in range(n):
            if px[i] == 0 and py[i] == 0:
                continue
            t = mpmath.atan2(mpmath.mpf(float(py[i])), mpmath.mpf(float(px[i])))
            if t == -mpmath.pi:  # atan2(-0.0, x<0): the angle is pi
                t = mpmath.pi
            assert mpmath.mpf(float(lo[i])) <= t <= mpmath.mpf(float(hi[i]))


def test_atan2_quadrants() -> None:
    def r(y, x):
        with iv.quiet():
            lo, hi = iv.atan2((A([y[0]]), A([y[1]])), (A([x[0]]), A([x[1]])))
        return float(lo[0]), float(hi[0])

    lo, hi = r((1, 2), (1, 2))  # first quadrant: corners
    assert lo <= math.atan2(1, 2) and hi >= math.atan2(2, 1) and hi - lo < 0.65
    assert r((-1, 1), (-2, -1)) == (-iv.PI_HI, iv.PI_HI)  # crosses the cut
    lo, hi = r((0, 1), (-2, -1))  # touches the cut from above: up to pi, not -pi
    assert lo > 2 and hi >= math.pi
    lo, hi = r((0, 1), (0, 1))  # origin at a corner: [0, pi/2]
    assert lo <= 0 and lo > -1e-15 and hi >= math.pi / 2 and hi < math.pi / 2 + 1e-14
    assert r((-1, 1), (-1, 1)) == (-iv.PI_HI, iv.PI_HI)
    # touches the cut from below: y = 0 gives pi, y < 0 gives angles near -pi
    lo, hi = r((-1, 0), (-2, -1))
    assert lo <= -math.pi + 1e-9 and hi >= math.pi
    lo, hi = r((-1, -0.0), (-2, -1))
    assert lo <= -math.pi + 1e-9 and hi >= math.pi
    lo, hi = r((-1, 1), (0, 1))  # origin on an edge: [-pi/2, pi/2]
    assert lo <= -math.pi / 2 and hi >= math.pi / 2 and hi - lo < math.pi + 1e-14


# -- pow ------------------------------------------------------------------------------------

@settings(max_examples=300, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_pow_sound(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = 30
    (lo, hi), x = rand_boxes(rng, n, inf_rate=0.05)
    lo, hi, x = np.clip(lo, -1e6, 1e6), np.clip(hi, -1e6, 1e6), np.clip(x, -1e6, 1e6)
    e = rng.choice([-5, -3, -2, -1, 2, 3, 4, 5, 7], n).astype(float)
    with iv.quiet():
        rlo, rhi = iv.pow_int((lo, hi), e)
    assert not np.isnan(rlo).any() and not np.isnan(rhi).any()
    for i in range(n):
        if x[i] == 0 and e[i] < 0:
            continue
        q = Fraction(x[i]) ** int(e[i])
        if abs(q) > Fraction(iv.MAX):
            continue
        assert frac_in(rlo[i], rhi[i], q), (lo[i], hi[i], x[i], e[i], rlo[i], rhi[i])


# -- sets, empties, NaN ---------------------------------------------------------------------

def test_empty_helpers() -> None:
    x = (A([1.0, 3.0, INF, -INF, 0.0]), A([2.0, 2.0, INF, -INF, 0.0]))
    assert iv.is_empty(x).tolist() == [False, True, True, True, False]
    lo, hi = iv.canon(x)
    assert lo[1] == INF and hi[1] == -INF and lo[0] == 1.0
    h = iv.hull(x, (A([5.0] * 5), A([6.0] * 5)))
    assert h[0].tolist() == [1.0, 5.0, 5.0, 5.0, 0.0] and h[1].tolist() == [6.0] * 5
    i = iv.intersect((A([0.0]), A([1.0])), (A([2.0]), A([3.0])))
    assert iv.is_empty(i)[0]
    e = iv.empty(3)
    assert iv.is_empty(e).all() and iv.empty(0)[0].shape == (0,)


RAW_UNARY = ["neg", "sqr", "sqrt", "exp", "log", "sin", "cos", "tan", "atan", "asin", "acos",
             "absv"]


def test_no_nan_on_special_intervals() -> None:
    ivs = [(a, b) for a, b in itertools.product(SPECIAL, SPECIAL) if a <= b and a < INF
           and b > -INF]
    lo = A([p[0] for p in ivs])
    hi = A([p[1] for p in ivs])
    pairs = list(itertools.product(range(len(ivs)), repeat=2))
    i1, i2 = A([p[0] for p in pairs]), A([p[1] for p in pairs])
    x, y = (lo[i1], hi[i1]), (lo[i2], hi[i2])
    with iv.quiet():
        for name in RAW_UNARY:
            r = getattr(iv, name)((lo, hi))
            assert not np.isnan(r[0]).any() and not np.isnan(r[1]).any(), name
        for name, fn in RAW.items():
            r = fn(x, y)
            assert not np.isnan(r[0]).any() and not np.isnan(r[1]).any(), name
        r = iv.atan2(x, y)
        assert not np.isnan(r[0]).any() and not np.isnan(r[1]).any()
        r = iv.pow_int((lo, hi), np.full(len(ivs), -3.0))
        assert not np.isnan(r[0]).any() and not np.isnan(r[1]).any()


def test_lengths_zero_and_one() -> None:
    with iv.quiet():
        for n in (0, 1):
            x = (np.zeros(n), np.ones(n))
            for name in RAW_UNARY:
                r = getattr(iv, name)(x)
                assert r[0].shape == (n,) and r[1].shape == (n,)
            for fn in RAW.values():
                assert fn(x, x)[0].shape == (n,)
            assert iv.atan2(x, x)[0].shape == (n,)
