"""Forward evaluation and backward projection of the two-argument primitives (add, sub,
mul, div, atan2), rounded outward.
"""

from __future__ import annotations

import numpy as np

from calib_dsl.arith import interval as iv
from calib_dsl.arith.boxes import empty_where, mul_project, mul_project_raw
from calib_dsl.arith.interval import (
    HALF_PI_HI,
    HALF_PI_LO,
    INF,
    PI_HI,
    PI_LO,
    Arr,
    Interval,
)


def fw_add(a: list[Interval], p: Arr | None) -> Interval:
    return iv.add(a[0], a[1])


def bw_add(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    return [iv.sub(z, a[1]), iv.sub(z, a[0])]


def fw_sub(a: list[Interval], p: Arr | None) -> Interval:
    return iv.sub(a[0], a[1])


def bw_sub(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    # z = x - y:  x = z + y,  y = x - z
    return [iv.add(z, a[1]), iv.sub(a[0], z)]


def fw_mul(a: list[Interval], p: Arr | None) -> Interval:
    return iv.mul(a[0], a[1])


def bw_mul(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    return [mul_project(z, a[1], a[0]), mul_project(z, a[0], a[1])]


def bw_mul_raw(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    return [mul_project_raw(z, a[1], a[0]), mul_project_raw(z, a[0], a[1])]


def fw_div(a: list[Interval], p: Arr | None) -> Interval:
    return iv.div(a[0], a[1])


def bw_div(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    # z = x / y  <=>  x = z * y with y != 0
    x, y = a
    zero = (y[0] == 0) & (y[1] == 0)  # y = 0 is no solution
    xs = empty_where(iv.mul(z, y), zero)
    ys = empty_where(mul_project(x, z, y), zero)
    return [xs, ys]


def fw_atan2(a: list[Interval], p: Arr | None) -> Interval:
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


def bw_atan2(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
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
    return [empty_where(ys, bad), empty_where(xs, bad)]
