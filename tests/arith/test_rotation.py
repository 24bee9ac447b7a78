"""The rotation contractor: soundness on exact random solutions, closeness to the optimal
5-variable projection (independent reference: exact polygon projection for each beta of a fine
grid), exactness for a point beta, beta recovery, empties, infinities, vectorization."""

from __future__ import annotations

import math

import mpmath  # exact references (a dev dependency)
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calib_dsl.arith.rotation import rot_contract

ENCLOSE_ULPS = 1  # references are exact (mpmath): one float outward
INF = math.inf
A = np.asarray


def I(lo: float, hi: float):  # noqa: E743
    return A([float(lo)]), A([float(hi)])


def ones(res) -> np.ndarray:
    return np.array([[r[0][0], r[1][0]] for r in res])


def exact_rot(b: float, u: float, v: float):
    with mpmath.workprec(300):
        c, s = mpmath.cos(mpmath.mpf(b)), mpmath.sin(mpmath.mpf(b))
        return u * c - v * s, u * s + v * c


def enclose(x) -> tuple[float, float]:
    lo = hi = float(x)
    for _ in range(ENCLOSE_ULPS):
        lo, hi = float(np.nextafter(lo, -INF)), float(np.nextafter(hi, INF))
    return lo, hi


# -- independent reference: the exact projection for fixed beta, on a beta grid --------------

def _clip(poly, a: float, b: float, c: float):
    """Sutherland-Hodgman: keep a*u + b*v <= c."""
    out = []
    for i in range(len(poly)):
        p, q = poly[i], poly[(i + 1) % len(poly)]
        fp, fq = a * p[0] + b * p[1] - c, a * q[0] + b * q[1] - c
        if fp <= 0:
            out.append(p)
        if (fp < 0 < fq) or (fq < 0 < fp):
            t = fp / (fp - fq)
            out.append((p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])))
    return out


def reference(b, u, v, u2, v2, nb: int = 801):
    """Inner approximation of the projections: for each beta of a grid, the polygon
    (u, v) box ∩ rot(beta)^-1 (u2, v2) box, projected exactly (vertices)."""
    res = None
    for beta in np.linspace(b[0], b[1], nb):
        c, s = math.cos(beta), math.sin(beta)
        poly = [(u[0], v[0]), (u[1], v[0]), (u[1], v[1]), (u[0], v[1])]
        for a_, b_, c_ in ((c, -s, u2[1]), (-c, s, -u2[0]), (s, c, v2[1]), (-s, -c, -v2[0])):
            poly = _clip(poly, a_, b_, c_)
            if not poly:
                break
        if not poly:
            continue
        p = np.array(poly)
        pu, pv = p[:, 0], p[:, 1]
        qu, qv = c * pu - s * pv, s * pu + c * pv
        cur = np.array([[beta, beta], [pu.min(), pu.max()], [pv.min(), pv.max()],
                        [qu.min(), qu.max()], [qv.min(), qv.max()]])
        if res is None:
            res = cur
        else:
            res[:, 0] = np.minimum(res[:, 0], cur[:, 0])
            res[:, 1] = np.maximum(res[:, 1], cur[:, 1])
    return res


def random_case(rng: np.random.Generator, wb: float, w: float, wout: float):
    b = rng.uniform(-math.pi, math.pi)
    u, v = rng.uniform(-1, 1, 2) * rng.uniform(0.1, 1)
    u2, v2 = u * math.cos(b) - v * math.sin(b), u * math.sin(b) + v * math.cos(b)

    def box(c: float, width: float):
        o = rng.uniform(0, width)
        return c - o, c - o + width
    return box(b, wb), box(u, w), box(v, w), box(u2, wout), box(v2, wout)


# -- soundness ------------------------------------------------------------------------------

def _draw_width(rng: np.random.Generator) -> float:
    return float(rng.choice([0.0, 1e-12, 1e-6, 1e-4, 1e-2, 0.5, 3.0, INF]))


@settings(max_examples=120, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_sound(seed: int) -> None:
    """A random exact solution, boxes of random widths around each coordinate (point to
    infinite, beta wide or near multiples of pi/2, u, v small or 0): every coordinate kept."""
    rng = np.random.default_rng(seed)
    n = 24
    pts, boxes = [], []
    for _ in range(n):
        k = rng.integers(0, 4)
        b = float(rng.uniform(-7, 7)) if k else float(rng.integers(-4, 5) * math.pi / 2)
        mag = 10.0 ** rng.uniform(-4, 1)
        u = float(rng.normal() * mag) if rng.random() > 0.1 else 0.0
        v = float(rng.normal() * mag) if rng.random() > 0.1 else 0.0
        u2x, v2x = exact_rot(b, u, v)
        pt = [b, u, v, u2x, v2x]
        encl = [(b, b), (u, u), (v, v), enclose(u2x), enclose(v2x)]
        bx = []
        for lo, hi in encl:
            w1, w2 = _draw_width(rng), _draw_width(rng)
            bx.append((lo - w1 * rng.random(), hi + w2 * rng.random()))
        pts.append(pt)
        boxes.append(bx)
    args = [(A([bx[j][0] for bx in boxes]), A([bx[j][1] for bx in boxes])) for j in range(5)]
    res = rot_contract(*args)
    for i in range(n):
        for j in range(5):
            lo, hi = res[j][0][i], res[j][1][i]
            assert not (math.isnan(lo) or math.isnan(hi))
            assert args[j][0][i] <= lo and hi <= args[j][1][i]
            p = pts[i][j]
            ok = mpmath.mpf(lo) <= p <= mpmath.mpf(hi) if j >= 3 else lo <= p <= hi
            assert ok, (i, j, boxes[i], pts[i], ones([(r[0][i:i + 1], r[1][i:i + 1])
                                                      for r in res]))


# -- closeness to the optimal projection ----------------------------------------------------

@pytest.mark.slow
@pytest.mark.parametrize("wb,w,wout", [(1e-5, 1e-4, 1e-4), (1e-3, 1e-4, 1e-4),
                                       (0.035, 1e-4, 1e-4), (0.2, 1e-4, 1e-4),
                                       (0.2, 1e-3, 1e-4), (1e-5, 1e-2, 1e-4)])
def test_near_optimal(wb: float, w: float, wout: float) -> None:
    """Typical calibration boxes: the result holds the reference (soundness) and exceeds it by
    little, measured in widths of the input box (beta: angle relation between box sectors;
    u, v, u2, v2: per-beta exact linear projection, evaluated over the beta interval)."""
    rng = np.random.default_rng(int(wb * 1e6) + int(w * 1e5))
    excess = []
    for _ in range(15):
        b, u, v, u2, v2 = random_case(rng, wb, w, wout)
        inp = np.array([b, u, v, u2, v2])
        r = ones(rot_contract(I(*b), I(*u), I(*v), I(*u2), I(*v2)))
        ref = reference(r[0], u, v, u2, v2)
        assert ref is not None
        assert (r[:, 0] <= ref[:, 0] + 1e-15).all() and (r[:, 1] >= ref[:, 1] - 1e-15).all()
        excess.append(np.maximum(ref[:, 0] - r[:, 0], r[:, 1] - ref[:, 1])
                      / (inp[:, 1] - inp[:, 0]))
    ex = np.array(excess)
    assert ex[:, 0].max() < 0.3 and ex[:, 1:].max() < 0.15, ex.max(axis=0)
    assert ex.mean() < 0.03, ex.mean(axis=0)


def test_point_beta_is_exact() -> None:
    """For a point beta the linear formulas give the exact projection (up to rounding)."""
    rng = np.random.default_rng(7)
    for _ in range(30):
        b, u, v, u2, v2 = random_case(rng, 0.0, 0.3, 0.3)
        r = ones(rot_contract(I(*b), I(*u), I(*v), I(*u2), I(*v2)))
        ref = reference(b, u, v, u2, v2, nb=1)
        assert np.abs(r[1:] - ref[1:]).max() < 1e-12, (r, ref)


@pytest.mark.parametrize("sweeps", [1, 2])
def test_forward_and_inverse_from_unbounded(sweeps: int) -> None:
    """Outputs unknown (the usual start of propagation): one sweep gives the rotated box, as
    optimal as the forward evaluation; and the same for the inverse direction."""
    b, u, v = 0.7, (0.3, 0.3001), (-0.2, -0.1999)
    c, s = math.cos(b), math.sin(b)
    free = (-INF, INF)
    r = ones(rot_contract(I(b, b), I(*u), I(*v), I(*free), I(*free), sweeps=sweeps))
    eu2 = (u[0] * c - v[1] * s, u[1] * c - v[0] * s)
    ev2 = (u[0] * s + v[0] * c, u[1] * s + v[1] * c)
    assert np.allclose(r[3], eu2, atol=1e-15) and np.allclose(r[4], ev2, atol=1e-15)
    r = ones(rot_contract(I(-b, -b), I(*free), I(*free), I(*u), I(*v), sweeps=sweeps))
    assert np.allclose(r[1], eu2, atol=1e-15) and np.allclose(r[2], ev2, atol=1e-15)


def test_diamond() -> None:
    """beta = 45 deg, (u, v) in [-1,1]^2 maps to the diamond |u2| + |v2| <= sqrt 2; with
    v2 in [1.2, 2] this forces |u2| <= sqrt 2 - 1.2: one pass of pairwise projections
    would not find it, the eliminated formulas do."""
    b = math.pi / 4
    r = ones(rot_contract(I(b, b), I(-1, 1), I(-1, 1), I(-2, 2), I(1.2, 2)))
    lim = math.sqrt(2) - 1.2
    assert abs(r[3, 0] + lim) < 1e-12 and abs(r[3, 1] - lim) < 1e-12
    assert abs(r[4, 1] - math.sqrt(2)) < 1e-12 and r[4, 0] == 1.2


def test_beta_recovered() -> None:
    """An unknown angle is found from the two boxes (the angle relation)."""
    rng = np.random.default_rng(3)
    for _ in range(20):
        b, u, v, u2, v2 = random_case(rng, 1e-9, 1e-4, 1e-4)
        bt = 0.5 * (b[0] + b[1])
        for dom in ((-math.pi, math.pi), (-INF, INF), (bt - 0.2, bt + 0.2)):
            r = ones(rot_contract(I(*dom), I(*u), I(*v), I(*u2), I(*v2)))
            rho = math.hypot(0.5 * (u[0] + u[1]), 0.5 * (v[0] + v[1]))
            if dom[0] == -INF:
                assert r[0, 0] == -INF  # nothing to say about which turn
                continue
            assert r[0, 0] <= bt <= r[0, 1] and r[0, 1] - r[0, 0] < 6e-4 / rho


def test_beta_across_the_cut() -> None:
    """Boxes straddling the negative u axis (polar angle +-pi): the angles are unwrapped."""
    b = 0.3
    u, v = -0.8, 0.0
    u2, v2 = u * math.cos(b) - v * math.sin(b), u * math.sin(b) + v * math.cos(b)
    w = 1e-4
    r = ones(rot_contract(I(-1, 1), I(u - w, u + w), I(v - w, v + w), I(u2 - w, u2 + w),
                          I(v2 - w, v2 + w)))
    assert r[0, 0] <= b <= r[0, 1] and r[0, 1] - r[0, 0] < 1e-3
    r = ones(rot_contract(I(-1, 1), I(u2 - w, u2 + w), I(v2 - w, v2 + w), I(u - w, u + w),
                          I(v - w, v + w)))
    assert r[0, 0] <= -b <= r[0, 1] and r[0, 1] - r[0, 0] < 1e-3


def test_norm_mismatch_is_empty() -> None:
    r = rot_contract(I(-INF, INF), I(0.9, 1.0), I(-0.1, 0.1), I(1.9, 2.1), I(-0.1, 0.1))
    for lo, hi in r:
        assert lo[0] == INF and hi[0] == -INF


def test_unknown_angle_norms_only() -> None:
    """beta unknown and (u, v) around the origin: only the norms can act."""
    r = ones(rot_contract(I(-INF, INF), I(-1, 1), I(-1, 1), I(0.5, 0.6), I(0.0, 0.1)))
    assert r[0].tolist() == [-INF, INF]
    assert (r[1:3, 0] >= -1).all() and (r[3:, :] == [[0.5, 0.6], [0.0, 0.1]]).all()


SPECIAL = [(-INF, INF), (0.0, 0.0), (-1.0, 1.0), (0.5, 0.6), (2.0, INF), (INF, -INF), (1.0, 0.0),
           (-INF, -1.0)]


def test_special_inputs() -> None:
    import itertools

    combos = list(itertools.product(range(len(SPECIAL)), repeat=5))[::7]
    args = [(A([SPECIAL[c[j]][0] for c in combos]), A([SPECIAL[c[j]][1] for c in combos]))
            for j in range(5)]
    with np.errstate(all="raise"):
        res = rot_contract(*args)
    for (lo, hi), (alo, ahi) in zip(res, args, strict=True):
        assert not np.isnan(lo).any() and not np.isnan(hi).any()
        e = lo > hi
        assert (lo[e] == INF).all() and (hi[e] == -INF).all()
        assert (lo[~e] >= alo[~e]).all() and (hi[~e] <= ahi[~e]).all()
    for i, c in enumerate(combos):
        if any(SPECIAL[k][0] > SPECIAL[k][1] for k in c):
            assert all(r[0][i] == INF for r in res)


@pytest.mark.parametrize("n", [0, 1, 5])
def test_lengths(n: int) -> None:
    b = np.linspace(0.1, 0.5, n)
    u, v = np.full(n, 0.3), np.full(n, -0.2)
    u2, v2 = u * np.cos(b) - v * np.sin(b), u * np.sin(b) + v * np.cos(b)
    res = rot_contract((b, b), (u - 1e-3, u + 1e-3), (v - 1e-3, v + 1e-3),
                       (u2 - 1e-3, u2 + 1e-3), (v2 - 1e-3, v2 + 1e-3))
    assert len(res) == 5 and all(r[0].shape == (n,) for r in res)
    if n:
        assert (res[3][0] <= u2).all() and (u2 <= res[3][1]).all()
