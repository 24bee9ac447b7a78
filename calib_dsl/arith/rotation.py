"""A dedicated contractor for the rotation constraint (u2, v2) = rot(beta, (u, v)):

    u2 = u cos b - v sin b,    v2 = u sin b + v cos b      (vectorized over arrays)

Each sweep applies, all sound (outward rounded):
1. the angle relation: beta = atan2(v2, u2) - atan2(v, u) (mod 2pi), when neither box holds the
   origin (polar angle ranges of the two boxes, unwrapped, no cut problem);
2. the *linear* relations: for fixed beta the constraint is linear in (u, v, u2, v2), and each
   variable's projection is attained at a vertex where two of the other three are at a bound.
   So each variable gets the three formulas that eliminate one of the others (for u2:
   u cos b - v sin b, (u - v2 sin b)/cos b, (v2 cos b - v)/sin b), intersected. The first
   (the rotation itself) is evaluated exactly over the interval beta by corners, the other two
   by interval arithmetic. For a point beta this is the exact (LP) projection; for an
   interval beta it is exact up to O(width(beta) * |(u, v)|);
3. equal norms u**2 + v**2 = u2**2 + v2**2, projected back on each coordinate.
See docs/soundness.md for what this achieves.
"""

from __future__ import annotations

import numpy as np

from calib_dsl.arith import interval as iv
from calib_dsl.arith.boxes import finish_box, periodic_hull, prepare_boxes, sqr_project
from calib_dsl.arith.interval import TWO_PI_LO, Arr, Interval

Bool = np.ndarray
Rot = tuple[Interval, Interval, Interval, Interval, Interval]


def rot_contract(beta: Interval, u: Interval, v: Interval, u2: Interval, v2: Interval,
                 sweeps: int = 2) -> Rot:
    """Contract (beta, u, v, u2, v2) under (u2, v2) = rot(beta, (u, v)); elementwise over
    arrays (broadcast to one shape). Returns the five contracted intervals, each a sub-interval
    of its input (all empty where the box has no solution). One sweep does nearly all the work;
    the second lets norms, angles and the linear relations feed each other once more."""
    with iv.quiet():
        boxes, e = prepare_boxes([beta, u, v, u2, v2])
        flat = np.broadcast_arrays(*(x for b in boxes for x in b))  # one shape for all
        b0, u0, v0, u20, v20 = ((flat[i], flat[i + 1]) for i in range(0, 10, 2))
        res = rot_contract_raw(b0, u0, v0, u20, v20, sweeps=sweeps)
        for r in res:  # no solution for one coordinate means no solution at all
            re = iv.empty_mask(r)
            e = re if e is None else e | re
        b, uu, vv, uu2, vv2 = (finish_box(r, e) for r in res)
        return b, uu, vv, uu2, vv2


def rot_contract_raw(beta: Interval, u: Interval, v: Interval, u2: Interval, v2: Interval,
                     sweeps: int = 2) -> Rot:
    """rot_contract on non-empty inputs, inside iv.quiet(); an element may come out empty
    in some coordinates only (the caller spreads emptiness)."""
    for _ in range(sweeps):
        beta = _angle_step(beta, u, v, u2, v2)
        c, s = iv.cos(beta), iv.sin(beta)
        u, v, u2, v2 = _linear_step(beta, c, s, u, v, u2, v2)
        u, v, u2, v2 = _norm_step(u, v, u2, v2)
    return beta, u, v, u2, v2


def _stack(*xs: Interval) -> Interval:
    return iv.rows(*(x[0] for x in xs)), iv.rows(*(x[1] for x in xs))


def _linear_step(beta: Interval, c: Interval, s: Interval, u: Interval, v: Interval,
                 u2: Interval, v2: Interval) -> tuple[Interval, Interval, Interval, Interval]:
    """Targets (u2, v2, u, v), each from three formulas, stacked so that one call serves all:
         A = S1 c + S2 s,   B = (S1 + S3 s) / c,   C = (S2 - S3 c) / s
    with S1 = (u, v, u2, v2), S2 = (-v, u, v2, -u2), S3 = (-v2, u2, v, -u). E.g. for u2:
    u cos b - v sin b,  (u - v2 sin b) / cos b,  (v2 cos b - v) / sin b.
    A (the rotation itself, forward and inverse) is evaluated exactly over the interval b by
    corners (_rotations); B and C by interval arithmetic."""
    nu, nv, nu2, nv2 = iv.neg(u), iv.neg(v), iv.neg(u2), iv.neg(v2)
    s1 = _stack(u, v, u2, v2)
    s2 = _stack(nv, u, v2, nu2)
    s3 = _stack(nv2, u2, v, nu)
    t = iv.intersect(_stack(u2, v2, u, v), _rotations(beta, u, v, u2, v2))
    t = iv.intersect(t, iv.div(iv.add(s1, iv.mul(s3, s)), c))
    t = iv.intersect(t, iv.div(iv.sub(s2, iv.mul(s3, c)), s))
    lo, hi = t
    return (lo[2], hi[2]), (lo[3], hi[3]), (lo[0], hi[0]), (lo[1], hi[1])


def _rotations(beta: Interval, u: Interval, v: Interval, u2: Interval,
               v2: Interval) -> Interval:
    """Exact ranges (up to rounding) over the boxes and the interval beta of
         u2 = u cos b - v sin b = rho cos(b + phi),   v2 = rho sin(b + phi),
         u = u2 cos b + v2 sin b = rho' cos(b - phi'),  v = -rho' sin(b - phi'),
    with (u, v) = rho (cos phi, sin phi), (u2, v2) = rho' (cos phi', sin phi'). For fixed b the
    extremes over a box are at corners, so each range is the hull over the 4 corners of the
    box of rho_c cos(B ± phi_c) (resp. sin): 8 corner rows, one cos and one sin call."""
    xs = iv.rows(u[0], u[0], u[1], u[1], u2[0], u2[0], u2[1], u2[1])
    ys = iv.rows(v[0], v[1], v[0], v[1], v2[0], v2[1], v2[0], v2[1])
    rho = iv.hypot_point(xs, ys)
    plo, phi = iv.atan2_point(ys, xs)
    # B + phi for the (u, v) corners, B - phi' for the (u2, v2) corners
    a = (np.concatenate([beta[0] + plo[:4], beta[0] - phi[4:]]),
         np.concatenate([beta[1] + phi[:4], beta[1] - plo[4:]]))
    a = iv.dn1(a[0]), iv.up1(a[1])
    c = iv.mul(rho, iv.cos(a))
    s = iv.mul(rho, iv.sin(a))
    lo = np.array([c[0][:4].min(axis=0), s[0][:4].min(axis=0),
                   c[0][4:].min(axis=0), -s[1][4:].max(axis=0)])
    hi = np.array([c[1][:4].max(axis=0), s[1][:4].max(axis=0),
                   c[1][4:].max(axis=0), -s[0][4:].min(axis=0)])
    # non-finite corners: no bound from this box (the other box's targets still get one)
    fin = np.isfinite(xs) & np.isfinite(ys)
    f1, f2 = fin[:4].all(axis=0), fin[4:].all(axis=0)
    finite = np.array([f1, f1, f2, f2])
    return np.where(finite, lo, -np.inf), np.where(finite, hi, np.inf)


def _norm_step(u: Interval, v: Interval, u2: Interval,
               v2: Interval) -> tuple[Interval, Interval, Interval, Interval]:
    """u**2 + v**2 = u2**2 + v2**2 =: n; then each square = n - the other square."""
    q = _stack(u, v, u2, v2)
    sq = iv.sqr(q)
    lo, hi = sq
    n = iv.intersect(iv.add((lo[0], hi[0]), (lo[1], hi[1])),
                     iv.add((lo[2], hi[2]), (lo[3], hi[3])))
    other = (lo[[1, 0, 3, 2]], hi[[1, 0, 3, 2]])
    qlo, qhi = sqr_project(iv.sub(n, other), q)
    bad = ~(n[0] <= n[1])  # the two norms cannot match: no solution
    qlo, qhi = np.where(bad, np.inf, qlo), np.where(bad, -np.inf, qhi)
    return (qlo[0], qhi[0]), (qlo[1], qhi[1]), (qlo[2], qhi[2]), (qlo[3], qhi[3])


def polar_range(u: Interval, v: Interval) -> tuple[Arr, Arr, Bool]:
    """Enclosure [lo, hi] of the polar angles of the box u × v (not wrapped to (-pi, pi]:
    the corners' angles are unwrapped around the centre's angle), and where it is valid: the
    box is finite, avoids the origin (then its angles form an arc narrower than pi, with the
    centre's angle inside and the extremes at corners) and the arc is narrower than 3 rad."""
    ul, uh, vl, vh = u[0] + 0.0, u[1] + 0.0, v[0] + 0.0, v[1] + 0.0
    us = iv.rows(ul, ul, uh, uh)
    vs = iv.rows(vl, vh, vl, vh)
    a = np.arctan2(vs, us)
    mid = np.arctan2(vl * 0.5 + vh * 0.5, ul * 0.5 + uh * 0.5)
    a = a + np.round((mid - a) * (0.5 / np.pi)) * TWO_PI_LO  # k in {-1, 0, 1}
    # |a| >= pi whenever k != 0, so 8 relative ulps also cover 2pi's error and the sum's rounding
    lo, hi = iv.lib_lo(a.min(axis=0)), iv.lib_hi(a.max(axis=0))
    ok = (ul > 0) | (uh < 0) | (vl > 0) | (vh < 0)
    ok &= np.isfinite(ul) & np.isfinite(uh) & np.isfinite(vl) & np.isfinite(vh)
    ok &= hi - lo < 3.0
    return lo, hi, ok


def _angle_step(beta: Interval, u: Interval, v: Interval, u2: Interval,
                v2: Interval) -> Interval:
    """beta in (angles of (u2, v2)) - (angles of (u, v)) + 2k pi."""
    lo, hi, ok = polar_range(_stack(u, u2), _stack(v, v2))
    ok = ok[0] & ok[1]
    if not ok.any():
        return beta
    d = iv.sub((lo[1], hi[1]), (lo[0], hi[0]))
    blo, bhi = periodic_hull(beta[0], beta[1], [d], TWO_PI_LO)
    return np.where(ok, blo, beta[0]), np.where(ok, bhi, beta[1])

