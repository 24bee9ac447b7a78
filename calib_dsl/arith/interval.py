"""Outward-rounded interval arithmetic on numpy arrays: the propagator's arithmetic core.

An interval array is a pair ``(lo, hi)`` of float64 arrays of one shape (or broadcastable
shapes). An element with ``lo > hi`` is empty; we produce empties as ``(+inf, -inf)``. Bounds may
be infinite. See docs/soundness.md for the guarantee and what it assumes of numpy/libm.

Two layers:

* ``down``, ``up``, ``is_empty``, ``canon``, ``intersect``, ``hull``, ``empty`` accept anything,
  including empty elements.
* The *raw* operations (``add``, ``mul``, ``sin``, ...) are the hot path: they assume every input
  element is non-empty (``lo <= hi``, ``lo < +inf``, ``hi > -inf``), never return NaN for such
  inputs, may return an empty element (``lo > hi``, not always canonical) when the result is
  empty, and must run inside ``quiet()`` (they compute ``inf - inf`` and friends on purpose and
  discard the NaN). ``projections.forward``/``backward`` wrap them for general inputs.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Arr = NDArray[np.float64]
Interval = tuple[Arr, Arr]

INF = float("inf")
MAX = float(np.finfo(np.float64).max)
# The double nearest pi is below pi: pi lies in [PI_LO, PI_HI] (one ulp wide). Halving and
# doubling are exact, so the same holds for pi/2 and 2pi.
PI_LO = float(np.pi)
PI_HI = float(np.nextafter(np.pi, np.inf))
HALF_PI_LO, HALF_PI_HI = PI_LO / 2, PI_HI / 2
TWO_PI_LO, TWO_PI_HI = 2 * PI_LO, 2 * PI_HI
INV_PI = 1.0 / np.pi  # only used to *locate* periods; errors are covered by explicit margins
# Elementary functions (sin, exp, atan2, pow, ...): numpy/glibc are within 1-2 ulps (numpy's own
# accuracy tests demand <= 1 ulp for float64); we widen by 8 ulps relative plus an absolute term
# that covers any error in the subnormal range.
LIB_REL = 2.0**-49
LIB_ABS = 2.0**-1022


def quiet() -> np.errstate:
    """Context in which the raw operations may run (they produce and discard inf - inf)."""
    return np.errstate(all="ignore")


# -- rounding -------------------------------------------------------------------------------

def down(x: Arr) -> Arr:
    """Next float toward -inf (+-inf left alone)."""
    x = np.asarray(x, dtype=np.float64)
    return np.where(x == INF, x, np.nextafter(x, -INF))


def up(x: Arr) -> Arr:
    """Next float toward +inf (+-inf left alone)."""
    x = np.asarray(x, dtype=np.float64)
    return np.where(x == -INF, x, np.nextafter(x, INF))


_EPS = 2.0**-52
_TINY = 2.0**-1074
_SMALL = 256  # below this many elements nextafter is cheaper than 5 arithmetic ops
# (the size across which dn1/up1 round by another rule: propagate/kernels.py shares a step
# only in arrays above it)
ROUNDING_SIZE = _SMALL


def dn1(x: Arr) -> Arr:
    """Lower bound of a correctly rounded (+ - * / sqrt) result x: one float down (`nextafter`)
    for small arrays; for large ones x - (|x| 2**-52 + 2**-1074), which is one or two floats
    down (|x| 2**-52 is at least an ulp of x, and rounding the difference to nearest cannot
    come back above x - ulp/2). Unlike `down`, an overflowed +inf becomes about MAX: the exact
    value is finite, so +inf would exclude it."""
    if x.size <= _SMALL:
        return np.nextafter(x, -INF)
    m = np.minimum(x, MAX)
    return m - (np.abs(m) * _EPS + _TINY)


def up1(x: Arr) -> Arr:
    """Upper bound of a correctly rounded result (an overflowed -inf becomes about -MAX)."""
    if x.size <= _SMALL:
        return np.nextafter(x, INF)
    m = np.maximum(x, -MAX)
    return m + (np.abs(m) * _EPS + _TINY)


def lib_lo(y: Arr) -> Arr:
    """Lower bound of an elementary-function value computed as y (<= a few ulps off)."""
    m = np.minimum(y, MAX)  # overflow: the exact value is >= ~MAX
    return m - (np.abs(m) * LIB_REL + LIB_ABS)


def lib_hi(y: Arr) -> Arr:
    """Upper bound of an elementary-function value computed as y."""
    m = np.maximum(y, -MAX)
    return m + (np.abs(m) * LIB_REL + LIB_ABS)


def _blo(y: Arr) -> Arr:
    """lib_lo for functions that cannot overflow (bounded range): one op cheaper."""
    return y - (np.abs(y) * LIB_REL + LIB_ABS)


def _bhi(y: Arr) -> Arr:
    return y + (np.abs(y) * LIB_REL + LIB_ABS)


# -- sets -----------------------------------------------------------------------------------

def empty(shape: int | tuple[int, ...]) -> Interval:
    return np.full(shape, INF), np.full(shape, -INF)


def empty_mask(x: Interval) -> NDArray[np.bool_]:
    """is_empty for use inside quiet() (inf - inf is how [inf, inf] is caught)."""
    return ~(x[1] - x[0] >= 0)


def is_empty(x: Interval) -> NDArray[np.bool_]:
    """Elementwise: does x hold no real number? (lo > hi, or [inf, inf], or [-inf, -inf])."""
    with quiet():
        return empty_mask(x)


def canon_raw(x: Interval) -> Interval:
    """canon for use inside quiet()."""
    e = empty_mask(x)
    if not e.any():
        return x
    return np.where(e, INF, x[0]), np.where(e, -INF, x[1])


def canon(x: Interval) -> Interval:
    """Make every empty element exactly (+inf, -inf); non-empty elements are unchanged."""
    with quiet():
        return canon_raw(x)


def intersect(x: Interval, y: Interval) -> Interval:
    """Elementwise intersection (empty stays empty: lo > hi)."""
    return np.maximum(x[0], y[0]), np.minimum(x[1], y[1])


def hull(x: Interval, y: Interval) -> Interval:
    """Smallest interval holding both (empty elements are ignored)."""
    ex, ey = is_empty(x), is_empty(y)
    lo = np.minimum(np.where(ex, INF, x[0]), np.where(ey, INF, y[0]))
    hi = np.maximum(np.where(ex, -INF, x[1]), np.where(ey, -INF, y[1]))
    return canon((lo, hi))


def rows(*xs: Arr) -> Arr:
    """Stack arrays as rows (broadcasting them first only when their shapes differ)."""
    if len({x.shape for x in xs}) == 1:
        return np.array(xs)
    return np.stack(np.broadcast_arrays(*xs))


def contains(x: Interval, v: Arr) -> NDArray[np.bool_]:
    return (x[0] <= v) & (v <= x[1])


def hull_in(x: Interval, pieces: list[tuple[Interval, NDArray[np.bool_] | None]]) -> Interval:
    """hull( x ∩ p for each valid piece p ): the optimal projection when the feasible set is a
    union of intervals. A piece is used where its mask is True (None: everywhere). Pieces may
    hold NaN where their mask is False (the comparisons below drop them)."""
    lo: Arr | None = None
    hi: Arr | None = None
    for (plo, phi), ok in pieces:
        ilo, ihi = np.maximum(x[0], plo), np.minimum(x[1], phi)
        good = ilo <= ihi
        if ok is not None:
            good = good & ok
        ilo, ihi = np.where(good, ilo, INF), np.where(good, ihi, -INF)
        lo = ilo if lo is None else np.minimum(lo, ilo)
        hi = ihi if hi is None else np.maximum(hi, ihi)
    assert lo is not None and hi is not None
    return lo, hi


# -- raw arithmetic (non-empty inputs, inside quiet()) ----------------------------------------

def neg(x: Interval) -> Interval:
    return -x[1], -x[0]


def _sum_dn(s: Arr) -> Arr:
    """Lower bound of a rounded sum s: s - |s| 2**-52 (at least an ulp below for normal s).
    A zero or subnormal sum is exact (gradual underflow), and stays as it is."""
    m = np.minimum(s, MAX)
    return m - np.abs(m) * _EPS


def _sum_up(s: Arr) -> Arr:
    m = np.maximum(s, -MAX)
    return m + np.abs(m) * _EPS


def add(x: Interval, y: Interval) -> Interval:
    # Round to nearest, then outward by at least the half ulp the exact sum may differ.
    return _sum_dn(x[0] + y[0]), _sum_up(x[1] + y[1])


def sub(x: Interval, y: Interval) -> Interval:
    return _sum_dn(x[0] - y[1]), _sum_up(x[1] - y[0])


def mul(x: Interval, y: Interval) -> Interval:
    a, b = x
    c, d = y
    p1, p2, p3, p4 = a * c, a * d, b * c, b * d
    # fmin/fmax skip the NaN of 0*inf: that corner's real value is 0, and whenever a bound is 0
    # the same 0 meets the other (finite, or opposite infinite) bound, so the extremes survive.
    rlo = np.fmin(np.fmin(p1, p2), np.fmin(p3, p4))
    rhi = np.fmax(np.fmax(p1, p2), np.fmax(p3, p4))
    lo, hi = dn1(rlo), up1(rhi)
    zero = (rlo == 0) | (rhi == 0) | np.isnan(rlo)  # NaN: only [0,0] * [-inf,inf]
    if zero.any():
        lo, hi = _exact_zero(rlo, rhi, lo, hi, x, y)
    return lo, hi


def _exact_zero(rlo: Arr, rhi: Arr, lo: Arr, hi: Arr, x: Interval,
                y: Interval) -> Interval:
    """A product bound that is 0 needs no widening unless some corner product underflowed,
    which needs a non-zero factor below 2**-537 in magnitude (else |product| >= 2**-1074)."""
    tiny = 2.0**-537

    def small(t: Arr) -> NDArray[np.bool_]:
        return (t != 0) & (np.abs(t) < tiny)

    safe = ~(small(x[0]) | small(x[1]) | small(y[0]) | small(y[1]))
    nan = np.isnan(rlo)
    lo = np.where(nan | ((rlo == 0) & safe), 0.0, lo)
    hi = np.where(nan | ((rhi == 0) & safe), 0.0, hi)
    return lo, hi


def div_pos(x: Interval, c: Arr, d: Arr) -> Interval:
    """x / y for y in [c, d] minus {0}, with 0 <= c <= d, d > 0 and c never -0.0."""
    a, b = x
    # c == 0 gives a/0 = +-inf (the half-line limit) or 0/0 = NaN, which fmin/fmax skip
    # (the other quotient is then the right bound).
    return dn1(np.fmin(a / c, a / d)), up1(np.fmax(b / c, b / d))


def div_pieces(x: Interval, y: Interval) -> tuple[Interval, NDArray[np.bool_],
                                                    Interval, NDArray[np.bool_]]:
    """x / (y minus {0}) as two pieces: from the positive and the negative part of y.
    Returns (pos, pos_ok, neg, neg_ok); a piece is meaningless where its mask is False."""
    c, d = y
    pos = div_pos(x, np.maximum(c, 0.0) + 0.0, d)  # + 0.0 turns -0.0 into +0.0
    nlo, nhi = div_pos(x, np.maximum(-d, 0.0) + 0.0, -c)
    return pos, d > 0, (-nhi, -nlo), c < 0


def div(x: Interval, y: Interval) -> Interval:
    """Hull of { a / b : a in x, b in y, b != 0 } (empty where y == [0, 0])."""
    if not ((y[0] <= 0) & (y[1] >= 0)).any():  # usual case: 0 in no divisor
        a, b = x
        c, d = y
        q1, q2, q3, q4 = a / c, a / d, b / c, b / d  # inf/inf NaN: skipped, see mul
        return (dn1(np.fmin(np.fmin(q1, q2), np.fmin(q3, q4))),
                up1(np.fmax(np.fmax(q1, q2), np.fmax(q3, q4))))
    pos, pok, ng, nok = div_pieces(x, y)
    whole = (np.full_like(pos[0], -INF), np.full_like(pos[0], INF))
    return hull_in(whole, [(pos, pok), (ng, nok)])


def mig_mag(x: Interval) -> tuple[Arr, Arr]:
    """min |v| and max |v| over v in x (exact)."""
    return np.maximum(np.maximum(x[0], -x[1]), 0.0), np.maximum(-x[0], x[1])


def absv(x: Interval) -> Interval:
    return mig_mag(x)


def sqr(x: Interval) -> Interval:
    mig, mag = mig_mag(x)
    return np.maximum(dn1(mig * mig), 0.0), up1(mag * mag)


def sqrt(x: Interval) -> Interval:
    """sqrt over x ∩ [0, inf) (IEEE sqrt is correctly rounded: one ulp outward)."""
    lo = np.maximum(dn1(np.sqrt(np.maximum(x[0], 0.0))), 0.0)
    hi = up1(np.sqrt(x[1]))  # NaN where x < 0: made empty below
    ok = x[1] >= 0
    return np.where(ok, lo, INF), np.where(ok, hi, -INF)


def exp(x: Interval) -> Interval:
    return np.maximum(lib_lo(np.exp(x[0])), 0.0), lib_hi(np.exp(x[1]))


def log(x: Interval) -> Interval:
    """log over x ∩ (0, inf) (empty if x <= 0)."""
    lo = lib_lo(np.log(np.maximum(x[0], 0.0)))
    hi = lib_hi(np.log(np.maximum(x[1], 0.0)))
    ok = x[1] > 0
    return np.where(ok, lo, INF), np.where(ok, hi, -INF)


def atan(x: Interval) -> Interval:
    return (np.maximum(_blo(np.arctan(x[0])), -HALF_PI_HI),
            np.minimum(_bhi(np.arctan(x[1])), HALF_PI_HI))


def asin(x: Interval) -> Interval:
    """asin over x ∩ [-1, 1]."""
    a, b = np.maximum(x[0], -1.0), np.minimum(x[1], 1.0)
    ok = a <= b
    lo = np.maximum(_blo(np.arcsin(np.minimum(a, 1.0))), -HALF_PI_HI)
    hi = np.minimum(_bhi(np.arcsin(np.maximum(b, -1.0))), HALF_PI_HI)
    return np.where(ok, lo, INF), np.where(ok, hi, -INF)


def acos(x: Interval) -> Interval:
    """acos over x ∩ [-1, 1] (decreasing)."""
    a, b = np.maximum(x[0], -1.0), np.minimum(x[1], 1.0)
    ok = a <= b
    lo = np.maximum(_blo(np.arccos(np.maximum(b, -1.0))), 0.0)
    hi = np.minimum(_bhi(np.arccos(np.minimum(a, 1.0))), PI_HI)
    return np.where(ok, lo, INF), np.where(ok, hi, -INF)


def pow_int(x: Interval, n: Arr) -> Interval:
    """x**n for integer n (elementwise, any sign; n = 0 gives 1, x**-k = 1/x**k)."""
    m = np.abs(n)
    even = np.floor(m * 0.5) * 2.0 == m
    mig, mag = mig_mag(x)
    blo, bhi = np.where(even, mig, x[0]), np.where(even, mag, x[1])
    # numpy.power on an integer-valued float exponent: libm pow (< 1 ulp, exact sign). The
    # extra m * 2**-53 relative would even cover a product-by-squaring implementation.
    plo, phi = np.minimum(np.power(blo, m), MAX), np.maximum(np.power(bhi, m), -MAX)
    rel = LIB_REL + m * 2.0**-53
    lo = plo - (np.abs(plo) * rel + LIB_ABS)
    hi = phi + (np.abs(phi) * rel + LIB_ABS)
    lo = np.where(even, np.maximum(lo, 0.0), lo)
    if (n < 0).any():
        rlo, rhi = div((np.ones_like(lo), np.ones_like(hi)), (lo, hi))
        lo, hi = np.where(n < 0, rlo, lo), np.where(n < 0, rhi, hi)
    return lo, hi


def root_lo(z: Arr, m: Arr) -> Arr:
    """Lower bound of z**(1/m) for z >= 0, m >= 1 an integer. pow(z, fl(1/m)) errs by a libm
    ulp plus the exponent's rounding, a relative |ln z| * 2**-53 / m."""
    r = np.power(z, 1.0 / m)
    rel = LIB_REL + np.minimum(np.abs(np.log(z)), 750.0) * 2.0**-52 / m
    r = np.minimum(r, MAX)
    return np.maximum(r - (r * rel + LIB_ABS), 0.0)


def root_hi(z: Arr, m: Arr) -> Arr:
    r = np.power(z, 1.0 / m)
    rel = LIB_REL + np.minimum(np.abs(np.log(z)), 750.0) * 2.0**-52 / m
    return r + (r * rel + LIB_ABS)


# -- periodic functions ---------------------------------------------------------------------

def _extrema(a: Arr, b: Arr, phase: float) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """Does [a, b] (possibly) contain phase + k*pi with k even / with k odd?

    q = (a - phase)/pi is computed with relative error < 3 * 2**-53 (plus 2**-54 absolute for
    phase's rounding); the margin (|q| + 1) * 2**-50 covers it, so an extremum is never missed.
    Infinite bounds give ka = -inf or kb = inf: both flags set. For |q| >= 2**50 the margin
    exceeds 1 and both flags are set too (no reliable k there)."""
    qa = (a - phase) * INV_PI
    qb = (b - phase) * INV_PI
    ka = np.ceil(qa - (np.abs(qa) + 1.0) * 2.0**-50)
    kb = np.floor(qb + (np.abs(qb) + 1.0) * 2.0**-50)
    n = kb - ka
    many = n >= 1
    one = n == 0
    ev = np.floor(ka * 0.5) * 2.0 == ka
    return many | (one & ev), many | (one & ~ev)


def _sincos(x: Interval, f: np.ufunc, phase: float) -> Interval:
    """Range of f in {sin, cos} over x: f = +1 at phase + 2k pi, -1 at phase + (2k+1) pi."""
    a, b = x
    has_max, has_min = _extrema(a, b, phase)
    fa, fb = f(a), f(b)  # NaN for infinite bounds: then both flags are set
    lo = np.where(has_min, -1.0, np.maximum(_blo(np.minimum(fa, fb)), -1.0))
    hi = np.where(has_max, 1.0, np.minimum(_bhi(np.maximum(fa, fb)), 1.0))
    return lo, hi


def sin(x: Interval) -> Interval:
    return _sincos(x, np.sin, HALF_PI_LO)


def cos(x: Interval) -> Interval:
    return _sincos(x, np.cos, 0.0)


def tan(x: Interval) -> Interval:
    """tan over x minus its poles: (-inf, inf) if x (possibly) holds a pole pi/2 + k pi."""
    a, b = x
    has_pole, has_pole_odd = _extrema(a, b, HALF_PI_LO)
    pole = has_pole | has_pole_odd
    return np.where(pole, -INF, lib_lo(np.tan(a))), np.where(pole, INF, lib_hi(np.tan(b)))


def atan2(y: Interval, x: Interval) -> Interval:
    """Range of the polar angle (-pi, pi] of the points of the box y × x (origin excluded).

    The box is convex: if it avoids the cut (y = 0, x < 0) and the origin is not interior, the
    extreme angles are at corners (a corner at the origin is skipped). Otherwise [-pi, pi]."""
    yl, yh = y[0] + 0.0, y[1] + 0.0  # + 0.0: no -0.0, so atan2(0, x<0) = +pi
    xl, xh = x[0] + 0.0, x[1] + 0.0
    ys = rows(yl, yh, yl, yh)
    xs = rows(xl, xl, xh, xh)
    t = np.arctan2(ys, xs)
    orig = (xl <= 0) & (xh >= 0) & (yl <= 0) & (yh >= 0)
    if orig.any():
        t = np.where((xs == 0) & (ys == 0), np.nan, t)  # the origin has no angle
    lo = np.maximum(_blo(np.fmin.reduce(t, axis=0)), -PI_HI)
    hi = np.minimum(_bhi(np.fmax.reduce(t, axis=0)), PI_HI)
    # Crosses (or touches from below) the cut y = 0, x < 0; this includes an interior origin.
    full = (xl < 0) & (yl < 0) & (yh >= 0)
    full |= np.isnan(lo)  # every corner at the origin
    return np.where(full, -PI_HI, lo), np.where(full, PI_HI, hi)


def hypot_point(u: Arr, v: Arr) -> Interval:
    """Enclosure of sqrt(u**2 + v**2) for point coordinates."""
    r = np.hypot(u, v)
    return np.maximum(lib_lo(r), 0.0), lib_hi(r)


def atan2_point(v: Arr, u: Arr) -> Interval:
    """Enclosure of the angle atan2(v, u) of a point (not the origin)."""
    t = np.arctan2(v + 0.0, u + 0.0)
    return np.maximum(_blo(t), -PI_HI), np.minimum(_bhi(t), PI_HI)
