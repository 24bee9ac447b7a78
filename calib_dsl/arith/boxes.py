"""What every projection does around its operation: empty inputs and outputs, the
intersection of a projection with its argument, and the projections shared by several
operators (the product, the square, periodic functions' hulls).
"""

from __future__ import annotations

import numpy as np

from calib_dsl.arith import interval as iv
from calib_dsl.arith.interval import (
    INF,
    Arr,
    Interval,
)

Bool = np.ndarray


def prepare_boxes(args: list[Interval]) -> tuple[list[Interval], Bool | None]:
    """float64 arrays, and the mask of elements where some interval is empty (replaced by
    [0, 0] so that the raw operations only ever see non-empty intervals)."""
    boxes = [(np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64))
             for lo, hi in args]
    e: Bool | None = None
    for b in boxes:
        be = iv.empty_mask(b)
        e = be if e is None else e | be
    if e is None or not e.any():
        return boxes, None
    return [(np.where(e, 0.0, lo), np.where(e, 0.0, hi)) for lo, hi in boxes], e


def finish_box(r: Interval, e: Bool | None) -> Interval:
    """Canonical empties where e. The raw operations return canonical empties or non-empty
    intervals, and backward folds its own empty results into e, so nothing else to fix."""
    if e is not None and e.any():
        return np.where(e, INF, r[0]), np.where(e, -INF, r[1])
    return r


def mul_project(out: Interval, other: Interval, cur: Interval) -> Interval:
    """Projection of `cur` from out = cur * other: cur ∩ out / other, with the extended
    division in two pieces (intersected with cur before the hull), and no contraction where
    0 is in both out and other (then any cur works)."""
    free = (out[0] <= 0) & (out[1] >= 0) & (other[0] <= 0) & (other[1] >= 0)
    pos, pok, neg, nok = iv.div_pieces(out, other)
    lo, hi = iv.hull_in(cur, [(pos, pok), (neg, nok)])
    return np.where(free, cur[0], lo), np.where(free, cur[1], hi)


def mul_project_raw(out: Interval, other: Interval, cur: Interval) -> Interval:
    """mul_project for non-empty inputs, element for element the same bounds, with a shortcut
    for the usual elements: where 0 is in no `other`, there is one piece, out / other (for a
    negative `other`, mul_project's mirrored piece -(out / -other) is the same quotients with
    the roles of out's bounds swapped: negation is exact, and dn1(-x) = -up1(x)); where 0 is
    in `other` and in `out`, cur is free. Any other element (0 in `other` only) takes the
    general mul_project."""
    c, d = other
    pos = c > 0
    one = pos | (d < 0)  # 0 is not in other
    free = None
    if not one.all():
        if not (one | ((out[0] <= 0) & (out[1] >= 0))).all():
            return mul_project(out, other, cur)
        free = ~one
    if pos.all():
        a, b = out
    else:
        a, b = np.where(pos, out[0], out[1]), np.where(pos, out[1], out[0])
    ilo = np.maximum(cur[0], iv.dn1(np.fmin(a / c, a / d)))
    ihi = np.minimum(cur[1], iv.up1(np.fmax(b / c, b / d)))
    good = ilo <= ihi
    lo, hi = np.where(good, ilo, INF), np.where(good, ihi, -INF)
    if free is None:
        return lo, hi
    return np.where(free, cur[0], lo), np.where(free, cur[1], hi)


def periodic_hull(a: Arr, b: Arr, families: list[tuple[Arr, Arr]],
                  period: float) -> Interval:
    """Hull of [a, b] ∩ S where S = union over k and families of [e + k P, x + k P].

    Each family gives the k = 0 component [e, x] as floats with e <= true entry, x >= true
    exit, up to the rounding of the one operation that computed them (|e|, |x| <= 2P); P is
    the float of the period (2pi or pi: true P within 2**-53 relative).
    The first point of S at or after a is bracketed soundly:
      * k = ceil((a - x)/P - da): the margin da covers the rounding of the quotient, so every
        component below k truly ends before a;
      * the entry of component k is computed as e + k P - Ma: with |k| P <= |a| + 3.1P, the
        errors (P's own, k*P's and the sum's rounding, e's rounding, the final subtraction) stay
        below (4|a| + 16.4P) 2**-53 < Ma = (|a| + 5P) 2**-51.
    Then the new lower bound is max(a, entry(k)). The upper bound is symmetric. Valid for any
    finite a (for huge |a| the bounds just stop moving) and for infinite a (no move).
    Returns (L, U); L > U (or L > b) means empty."""
    inv = 1.0 / period
    absa, absb = np.abs(a), np.abs(b)
    ma = (absa + 5.0 * period) * 2.0**-51
    mb = (absb + 5.0 * period) * 2.0**-51
    da = (absa * inv + 8.0) * 2.0**-47
    db = (absb * inv + 8.0) * 2.0**-47
    lo: Arr | None = None
    hi: Arr | None = None
    for e, x in families:
        k = np.ceil((a - x) * inv - da)
        lo_f = np.fmax(a, (e + k * period) - ma)  # fmax: a = -inf gives -inf, not NaN
        k = np.floor((b - e) * inv + db)
        hi_f = np.fmin(b, (x + k * period) + mb)
        lo = lo_f if lo is None else np.fmin(lo, lo_f)
        hi = hi_f if hi is None else np.fmax(hi, hi_f)
    assert lo is not None and hi is not None
    return lo, hi


def empty_where(x: Interval, bad: Bool) -> Interval:
    return np.where(bad, INF, x[0]), np.where(bad, -INF, x[1])


def sqr_project(z: Interval, x: Interval) -> Interval:
    """Projection of x from z = x**2: ±sqrt(z ∩ [0, inf)), both branches cut by x, hull."""
    ok = z[1] >= 0
    rlo = np.maximum(iv.dn1(np.sqrt(np.maximum(z[0], 0.0))), 0.0)
    rhi = iv.up1(np.sqrt(z[1]))
    return iv.hull_in(x, [((rlo, rhi), ok), ((-rhi, -rlo), ok)])
