"""Forward evaluation and backward projection of the one-argument primitives (neg, sqr, abs,
sqrt, exp, log, sin, cos, tan, pow), rounded outward.
"""

from __future__ import annotations

import numpy as np

from calib_dsl.arith import interval as iv
from calib_dsl.arith.boxes import Bool, empty_where, periodic_hull, sqr_project
from calib_dsl.arith.interval import (
    INF,
    PI_HI,
    PI_LO,
    TWO_PI_LO,
    Arr,
    Interval,
)


def fw_neg(a: list[Interval], p: Arr | None) -> Interval:
    return iv.neg(a[0])


def bw_neg(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    return [iv.neg(z)]


def fw_sqr(a: list[Interval], p: Arr | None) -> Interval:
    return iv.sqr(a[0])


def bw_sqr(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    return [sqr_project(z, a[0])]


def fw_abs(a: list[Interval], p: Arr | None) -> Interval:
    return iv.absv(a[0])


def bw_abs(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    ok = z[1] >= 0
    zl = np.maximum(z[0], 0.0)
    return [iv.hull_in(a[0], [((zl, z[1]), ok), ((-z[1], -zl), ok)])]


def fw_sqrt(a: list[Interval], p: Arr | None) -> Interval:
    return iv.sqrt(a[0])


def bw_sqrt(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    zl = np.maximum(z[0], 0.0)
    lo = np.maximum(iv.dn1(zl * zl), 0.0)  # x >= 0
    return [empty_where((lo, iv.up1(z[1] * z[1])), z[1] < 0)]


def fw_exp(a: list[Interval], p: Arr | None) -> Interval:
    return iv.exp(a[0])


def bw_exp(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    return [iv.log(z)]


def fw_log(a: list[Interval], p: Arr | None) -> Interval:
    return iv.log(a[0])


def bw_log(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    return [iv.exp(z)]


def fw_sin(a: list[Interval], p: Arr | None) -> Interval:
    return iv.sin(a[0])


def fw_cos(a: list[Interval], p: Arr | None) -> Interval:
    return iv.cos(a[0])


def fw_tan(a: list[Interval], p: Arr | None) -> Interval:
    return iv.tan(a[0])


def bw_sin(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    # sin x in [c, d]  <=>  x in [asin c, asin d] or [pi - asin d, pi - asin c]  (mod 2pi)
    c, d = np.maximum(z[0], -1.0), np.minimum(z[1], 1.0)
    al, _ = iv.asin((c, c))
    _, bh = iv.asin((d, d))
    fam = [(al, bh), (PI_LO - bh, PI_HI - al)]
    lo, hi = periodic_hull(a[0][0], a[0][1], fam, TWO_PI_LO)
    return [empty_where((lo, hi), ~(c <= d))]


def bw_cos(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    # cos x in [c, d]  <=>  x in [acos d, acos c] or [-acos c, -acos d]  (mod 2pi)
    c, d = np.maximum(z[0], -1.0), np.minimum(z[1], 1.0)
    g1, _ = iv.acos((d, d))
    _, g2 = iv.acos((c, c))
    lo, hi = periodic_hull(a[0][0], a[0][1], [(g1, g2), (-g2, -g1)], TWO_PI_LO)
    return [empty_where((lo, hi), ~(c <= d))]


def bw_tan(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
    # tan x in [c, d]  <=>  x in [atan c, atan d]  (mod pi)
    t1, _ = iv.atan((z[0], z[0]))
    _, t2 = iv.atan((z[1], z[1]))
    return [periodic_hull(a[0][0], a[0][1], [(t1, t2)], PI_LO)]


def fw_pow(a: list[Interval], p: Arr | None) -> Interval:
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


def bw_pow(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
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
