"""Forward evaluation and backward projections of the primitive constraints, vectorized.

``forward(op, args, param)`` encloses { f(x1..xk) : xi in args[i] }, rounded outward.
``backward(op, out, args, param)`` returns, for each argument, a sub-interval of it holding every
value that takes part in a solution of ``out = f(args)`` inside the box (the projection). The
projections are the hull of the exact projection, up to outward rounding, except where noted
(atan2, rotu/rotv): see docs/soundness.md.

Every call costs a bounded number of numpy calls whatever the array length.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from calib_dsl.arith import interval as iv
from calib_dsl.arith.interval import (
    HALF_PI_HI,
    HALF_PI_LO,
    INF,
    PI_HI,
    PI_LO,
    TWO_PI_LO,
    Arr,
    Interval,
)

Bool = np.ndarray


# -- entry points ---------------------------------------------------------------------------

def forward(op: str, args: list[Interval], param: Arr | None = None) -> Interval:
    """An outward-rounded enclosure of { f(x1..xk) : xi in args[i] } (elementwise)."""
    fn = _FORWARD.get(op)
    if fn is None:
        raise ValueError(f"unknown primitive {op!r}")
    with iv.quiet():
        boxes, e = prepare_boxes(args)
        lo, hi = fn(boxes, param)
        return finish_box((lo, hi), e)


def backward(op: str, out: Interval, args: list[Interval],
             param: Arr | None = None) -> list[Interval]:
    """For each argument, the hull of its values in the solutions of out = f(args) (a
    sub-interval of args[i]); every argument is empty where the box holds no solution."""
    fn = _BACKWARD.get(op)
    if fn is None:
        raise ValueError(f"unknown primitive {op!r}")
    with iv.quiet():
        boxes, e = prepare_boxes([out, *args])
        res = fn(boxes[0], boxes[1:], param)
        res = [iv.intersect(r, a) for r, a in zip(res, boxes[1:], strict=True)]
        for r in res:  # no solution for one argument means no solution at all
            re = iv.empty_mask(r)
            e = re if e is None else e | re
        if e is not None and e.any():
            return [(np.where(e, INF, r[0]), np.where(e, -INF, r[1])) for r in res]
        return res


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


# -- shared projection helpers --------------------------------------------------------------

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


def _empty_where(x: Interval, bad: Bool) -> Interval:
    return np.where(bad, INF, x[0]), np.where(bad, -INF, x[1])


# -- unary ----------------------------------------------------------------------------------

def _fw_neg(a: list[Interval], p: Arr | None) -> Interval:
    return iv.neg(a[0])


def _bw_neg(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    return [iv.neg(z)]


def _fw_sqr(a: list[Interval], p: Arr | None) -> Interval:
    return iv.sqr(a[0])


def sqr_project(z: Interval, x: Interval) -> Interval:
    """Projection of x from z = x**2: ±sqrt(z ∩ [0, inf)), both branches cut by x, hull."""
    ok = z[1] >= 0
    rlo = np.maximum(iv.dn1(np.sqrt(np.maximum(z[0], 0.0))), 0.0)
    rhi = iv.up1(np.sqrt(z[1]))
    return iv.hull_in(x, [((rlo, rhi), ok), ((-rhi, -rlo), ok)])


def _bw_sqr(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    return [sqr_project(z, a[0])]


def _fw_abs(a: list[Interval], p: Arr | None) -> Interval:
    return iv.absv(a[0])


def _bw_abs(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    ok = z[1] >= 0
    zl = np.maximum(z[0], 0.0)
    return [iv.hull_in(a[0], [((zl, z[1]), ok), ((-z[1], -zl), ok)])]


def _fw_sqrt(a: list[Interval], p: Arr | None) -> Interval:
    return iv.sqrt(a[0])


def _bw_sqrt(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    zl = np.maximum(z[0], 0.0)
    lo = np.maximum(iv.dn1(zl * zl), 0.0)  # x >= 0
    return [_empty_where((lo, iv.up1(z[1] * z[1])), z[1] < 0)]


def _fw_exp(a: list[Interval], p: Arr | None) -> Interval:
    return iv.exp(a[0])


def _bw_exp(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    return [iv.log(z)]


def _fw_log(a: list[Interval], p: Arr | None) -> Interval:
    return iv.log(a[0])


def _bw_log(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    return [iv.exp(z)]


def _fw_sin(a: list[Interval], p: Arr | None) -> Interval:
    return iv.sin(a[0])


def _fw_cos(a: list[Interval], p: Arr | None) -> Interval:
    return iv.cos(a[0])


def _fw_tan(a: list[Interval], p: Arr | None) -> Interval:
    return iv.tan(a[0])


def _bw_sin(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    # sin x in [c, d]  <=>  x in [asin c, asin d] or [pi - asin d, pi - asin c]  (mod 2pi)
    c, d = np.maximum(z[0], -1.0), np.minimum(z[1], 1.0)
    al, _ = iv.asin((c, c))
    _, bh = iv.asin((d, d))
    fam = [(al, bh), (PI_LO - bh, PI_HI - al)]
    lo, hi = periodic_hull(a[0][0], a[0][1], fam, TWO_PI_LO)
    return [_empty_where((lo, hi), ~(c <= d))]


def _bw_cos(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    # cos x in [c, d]  <=>  x in [acos d, acos c] or [-acos c, -acos d]  (mod 2pi)
    c, d = np.maximum(z[0], -1.0), np.minimum(z[1], 1.0)
    g1, _ = iv.acos((d, d))
    _, g2 = iv.acos((c, c))
    lo, hi = periodic_hull(a[0][0], a[0][1], [(g1, g2), (-g2, -g1)], TWO_PI_LO)
    return [_empty_where((lo, hi), ~(c <= d))]


def _bw_tan(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    # tan x in [c, d]  <=>  x in [atan c, atan d]  (mod pi)
    t1, _ = iv.atan((z[0], z[0]))
    _, t2 = iv.atan((z[1], z[1]))
    return [periodic_hull(a[0][0], a[0][1], [(t1, t2)], PI_LO)]


def _fw_pow(a: list[Interval], p: Arr | None) -> Interval:
    assert p is not None, "pow needs its exponent as param"
    return iv.pow_int(a[0], np.asarray(p, dtype=np.float64))


def _root_branch(z: Interval, m: Arr, negative: Bool) -> tuple[Arr, Arr, Bool]:
    """{ w >= 0 : w**n in z } for n = ±m (m >= 1): an interval, and where it is non-empty."""
    ok = z[1] >= 0
    zl = np.maximum(z[0], 0.0)
    rlo, rhi = iv.root_lo(zl, m), iv.root_hi(np.maximum(z[1], 0.0), m)
    # n < 0: w = 1 / z**(1/m), decreasing
    nlo = np.maximum(iv.dn1(1.0 / rhi), 0.0)
    nhi = iv.up1(1.0 / rlo)
    return np.where(negative, nlo, rlo), np.where(negative, nhi, rhi), ok


def _bw_pow(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    assert p is not None, "pow needs its exponent as param"
    n = np.asarray(p, dtype=np.float64)
    m = np.maximum(np.abs(n), 1.0)
    even = np.floor(m * 0.5) * 2.0 == m
    negative = n < 0
    plo, phi, pok = _root_branch(z, m, negative)  # x >= 0: x**n = z
    zn = (np.where(even, z[0], -z[1]), np.where(even, z[1], -z[0]))  # x <= 0: |x|**n = ±z
    nlo, nhi, nok = _root_branch(zn, m, negative)
    x = iv.hull_in(a[0], [((plo, phi), pok), ((-nhi, -nlo), nok)])
    n0 = n == 0  # x**0 = 1: any x if 1 is in z
    if n0.any():
        keep = n0 & (z[0] <= 1) & (z[1] >= 1)
        x = (np.where(keep, a[0][0], np.where(n0, INF, x[0])),
             np.where(keep, a[0][1], np.where(n0, -INF, x[1])))
    return [x]


# -- binary ---------------------------------------------------------------------------------

def _fw_add(a: list[Interval], p: Arr | None) -> Interval:
    return iv.add(a[0], a[1])


def _bw_add(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    return [iv.sub(z, a[1]), iv.sub(z, a[0])]


def _fw_sub(a: list[Interval], p: Arr | None) -> Interval:
    return iv.sub(a[0], a[1])


def _bw_sub(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    # z = x - y:  x = z + y,  y = x - z
    return [iv.add(z, a[1]), iv.sub(a[0], z)]


def _fw_mul(a: list[Interval], p: Arr | None) -> Interval:
    return iv.mul(a[0], a[1])


def _bw_mul(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    return [mul_project(z, a[1], a[0]), mul_project(z, a[0], a[1])]


def _bw_mul_raw(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    return [mul_project_raw(z, a[1], a[0]), mul_project_raw(z, a[0], a[1])]


def _fw_div(a: list[Interval], p: Arr | None) -> Interval:
    return iv.div(a[0], a[1])


def _bw_div(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    # z = x / y  <=>  x = z * y with y != 0
    x, y = a
    zero = (y[0] == 0) & (y[1] == 0)  # y = 0 is no solution
    xs = _empty_where(iv.mul(z, y), zero)
    ys = _empty_where(mul_project(x, z, y), zero)
    return [xs, ys]


def _fw_atan2(a: list[Interval], p: Arr | None) -> Interval:
    return iv.atan2(a[0], a[1])


def _cot_lo(t: Arr) -> Arr:
    return iv.lib_lo(1.0 / np.tan(t))  # tan (<= 2 ulps) then 1/t (half an ulp): < 8 ulps


def _cot_hi(t: Arr) -> Arr:
    return iv.lib_hi(1.0 / np.tan(t))


def _nonneg_div(a: Interval, b: Interval) -> Interval:
    """{ w >= 0 : w * t = s for some s in a, t in b } for a, b inside [0, inf) (possibly empty,
    lo > hi): t = 0 needs s = 0 and then leaves w free; else w = s / t."""
    free = (a[0] <= 0) & (b[0] <= 0)
    lo = np.maximum(iv.dn1(a[0] / b[1]), 0.0)
    hi = iv.up1(a[1] / b[0])
    bad = (a[0] > a[1]) | (b[0] > b[1])
    lo = np.where(bad, INF, np.where(free, 0.0, lo))
    return lo, np.where(bad, -INF, np.where(free, INF, hi))


def _cone_half(out: Interval, t: Interval, cur: Interval, sign: float) -> Interval:
    """Projection of cur from out = cur * t when cur is confined to one sign (sign * cur >= 0):
    the sign of out is then sign * sign(t), so each half of t meets one half of out. Unlike
    mul_project this never keeps 0 as a limit reached from the other side of 0."""
    op = (np.maximum(out[0], 0.0), out[1])      # out ∩ [0, inf)
    on = (np.maximum(-out[1], 0.0), -out[0])    # -(out ∩ (-inf, 0])
    tp = (np.maximum(t[0], 0.0), t[1])
    tn = (np.maximum(-t[1], 0.0), -t[0])
    if sign > 0:
        w1, w2 = _nonneg_div(op, tp), _nonneg_div(on, tn)
        return iv.hull_in(cur, [(w1, None), (w2, None)])
    w1, w2 = _nonneg_div(on, tp), _nonneg_div(op, tn)
    return iv.hull_in(cur, [(iv.neg(w1), None), (iv.neg(w2), None)])


def _bw_atan2(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    """(x, y) = r (cos t, sin t), r > 0, t in z.  For x: on the half-plane x >= 0,
    y = x tan t with t in z ∩ [-pi/2, pi/2]; on x <= 0, y = x tan t with t in z taken mod 2pi
    inside [pi/2, 3pi/2]: sign-aware products (_cone_half) with the tan range. For y: the same
    with x = y cot t on y >= 0 (t in [0, pi]) and y <= 0 (t in [-pi, 0]). Sound; optimal up to
    rounding except that the left half uses the hull of its two angle pieces when z holds both
    pi/2 and -pi/2 (the tan range then misses a wedge around pi)."""
    y, x = a
    zl, zh = np.maximum(z[0], -PI_HI), np.minimum(z[1], PI_HI)
    bad = ~(zl <= zh)
    tl, th = np.tan(zl), np.tan(zh)
    # -- x: right half-plane, angles in [-pi/2, pi/2]
    r_ok = (zl <= HALF_PI_HI) & (zh >= -HALF_PI_HI)
    t_r = (np.where(zl <= -HALF_PI_LO, -INF, iv.lib_lo(tl)),
           np.where(zh >= HALF_PI_LO, INF, iv.lib_hi(th)))
    x_r = _cone_half(y, t_r, (np.maximum(x[0], 0.0), x[1]), 1.0)
    # -- x: left half-plane, pieces [pi/2, pi] and [-pi, -pi/2] (= [pi, 3pi/2])
    l1 = zh >= HALF_PI_LO
    l2 = zl <= -HALF_PI_LO
    t1lo = np.where(zl <= HALF_PI_HI, -INF, iv.lib_lo(tl))
    t2hi = np.where(zh >= -HALF_PI_HI, INF, iv.lib_hi(th))
    t_l = (np.where(l1, t1lo, iv.lib_lo(tl)), np.where(l2, t2hi, iv.lib_hi(th)))
    x_l = _cone_half(y, t_l, (x[0], np.minimum(x[1], 0.0)), -1.0)
    xs = iv.hull_in(x, [(x_r, r_ok), (x_l, l1 | l2)])
    # -- y: upper half-plane, angles [0, pi], cot decreasing
    u_ok = zh >= 0
    c_u = (np.where(zh >= PI_LO, -INF, _cot_lo(zh)), np.where(zl <= 0, INF, _cot_hi(zl)))
    y_u = _cone_half(x, c_u, (np.maximum(y[0], 0.0), y[1]), 1.0)
    # -- y: lower half-plane, angles [-pi, 0] (the angle pi alone is y = 0: in y_u already)
    d_ok = zl <= 0
    c_d = (np.where(zh >= 0, -INF, _cot_lo(zh)), np.where(zl <= -PI_LO, INF, _cot_hi(zl)))
    y_d = _cone_half(x, c_d, (y[0], np.minimum(y[1], 0.0)), -1.0)
    ys = iv.hull_in(y, [(y_u, u_ok), (y_d, d_ok)])
    return [_empty_where(ys, bad), _empty_where(xs, bad)]


# -- ternary: rotation outputs --------------------------------------------------------------

def rot_forward(beta: Interval, u: Interval, v: Interval, which: str) -> Interval:
    """rotu = u cos b - v sin b = rho cos(b + phi), rotv = rho sin(b + phi) with (u, v) =
    rho (cos phi, sin phi). For fixed b the extremes over the (u, v) box are at corners, so the
    exact range is the hull over the 4 corners of rho_c * cos(B + phi_c) (resp. sin): optimal
    up to rounding (a few ulps of rho, phi, cos each). Intersected with the plain interval
    formula, which is tighter for a point-like b (fewer roundings) and the only one used for
    non-finite u, v."""
    c, s = iv.cos(beta), iv.sin(beta)
    if which == "rotu":
        nlo, nhi = iv.sub(iv.mul(u, c), iv.mul(v, s))
    else:
        nlo, nhi = iv.add(iv.mul(u, s), iv.mul(v, c))
    f = iv.cos if which == "rotu" else iv.sin
    us = iv.rows(u[0], u[0], u[1], u[1])
    vs = iv.rows(v[0], v[1], v[0], v[1])
    finite = np.isfinite(us).all(axis=0) & np.isfinite(vs).all(axis=0)
    t = iv.mul(iv.hypot_point(us, vs), f(iv.add(beta, iv.atan2_point(vs, us))))
    lo, hi = np.maximum(t[0].min(axis=0), nlo), np.minimum(t[1].max(axis=0), nhi)
    if finite.all():
        return lo, hi
    return np.where(finite, lo, nlo), np.where(finite, hi, nhi)


def _fw_rotu(a: list[Interval], p: Arr | None) -> Interval:
    return rot_forward(a[0], a[1], a[2], "rotu")


def _fw_rotv(a: list[Interval], p: Arr | None) -> Interval:
    return rot_forward(a[0], a[1], a[2], "rotv")


def _bw_rot(which: str) -> Callable[[Interval, list[Interval], Arr | None], list[Interval]]:
    def bw(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
        # One output alone: the joint rotation contractor with the other output free.
        from calib_dsl.arith.rotation import (
            rot_contract_raw,  # late import: rotation builds on this module
        )

        free = (np.full_like(z[0], -INF), np.full_like(z[0], INF))
        u2, v2 = (z, free) if which == "rotu" else (free, z)
        b, u, v, _, _ = rot_contract_raw(a[0], a[1], a[2], u2, v2)
        return [b, u, v]
    return bw


_FORWARD: dict[str, Callable[[list[Interval], Arr | None], Interval]] = {
    "neg": _fw_neg, "sqr": _fw_sqr, "sqrt": _fw_sqrt, "exp": _fw_exp, "log": _fw_log,
    "sin": _fw_sin, "cos": _fw_cos, "tan": _fw_tan, "abs": _fw_abs, "pow": _fw_pow,
    "add": _fw_add, "sub": _fw_sub, "mul": _fw_mul, "div": _fw_div, "atan2": _fw_atan2,
    "rotu": _fw_rotu, "rotv": _fw_rotv,
}

_BACKWARD: dict[str, Callable[[Interval, list[Interval], Arr | None], list[Interval]]] = {
    "neg": _bw_neg, "sqr": _bw_sqr, "sqrt": _bw_sqrt, "exp": _bw_exp, "log": _bw_log,
    "sin": _bw_sin, "cos": _bw_cos, "tan": _bw_tan, "abs": _bw_abs, "pow": _bw_pow,
    "add": _bw_add, "sub": _bw_sub, "mul": _bw_mul, "div": _bw_div, "atan2": _bw_atan2,
    "rotu": _bw_rot("rotu"), "rotv": _bw_rot("rotv"),
}

# Raw backward projections for `propagate`'s fast sweep (non-empty inputs, inside quiet(), the
# caller intersects with the arguments): where they differ from _BACKWARD, they are faster and
# give the same bounds, element for element.
_FAST_BACKWARD: dict[str, Callable[[Interval, list[Interval], Arr | None], list[Interval]]] = {
    "mul": _bw_mul_raw,
}
