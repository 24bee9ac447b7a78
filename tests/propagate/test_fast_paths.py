"""The propagator's fast paths give the same bounds as the general projections, and keep the
truth: `bw_mul_raw` (the mul projection of the fast sweep) and `rot_contract_raw`."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from calib_dsl.arith import interval as iv
from calib_dsl.arith.binary import bw_mul_raw
from calib_dsl.arith.projections import backward
from calib_dsl.arith.rotation import rot_contract, rot_contract_raw

INF = math.inf
SPECIAL = [-INF, -1e300, -3.0, -1.0, -1e-310, -0.0, 0.0, 1e-310, 0.5, 2.0, 1e300, INF]
bound = st.one_of(st.sampled_from(SPECIAL), st.floats(-10, 10, allow_nan=False))


@st.composite
def interval(draw):
    a, b = sorted([draw(bound), draw(bound)])
    if a == INF or b == -INF:  # an interval holds a real number
        a, b = -1.0, 1.0
    return a, b


def _arrays(ivs):
    return np.array([x[0] for x in ivs], float), np.array([x[1] for x in ivs], float)


def _same(a, b) -> bool:
    """Equal bounds, every empty element counted as one empty interval."""
    ea, eb = a[0] > a[1], b[0] > b[1]
    ok = (ea == eb) & (ea | ((a[0] == b[0]) & (a[1] == b[1])))
    return bool(np.all(ok))


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(interval(), interval(), interval()), min_size=1, max_size=40))
def test_fast_mul_projection_equals_the_general_one(triples) -> None:
    z = _arrays([t[0] for t in triples])
    x = _arrays([t[1] for t in triples])
    y = _arrays([t[2] for t in triples])
    general = backward("mul", z, [x, y])
    with iv.quiet():
        raw = bw_mul_raw(z, [x, y], None)
    nonempty_all = np.all([g[0] <= g[1] for g in general], axis=0)
    for g, r, arg in zip(general, raw, (x, y), strict=True):
        fast = (np.maximum(r[0], arg[0]), np.minimum(r[1], arg[1]))
        keep = nonempty_all  # where the general one finds no solution, only emptiness counts
        assert _same((g[0][keep], g[1][keep]), (fast[0][keep], fast[1][keep]))


@settings(max_examples=300, deadline=None)
@given(st.floats(-4, 4), st.floats(-2, 2), st.floats(-2, 2),
       st.lists(st.floats(1e-9, 0.5), min_size=5, max_size=5))
def test_fast_rotation_contractor_keeps_the_truth(beta, u, v, radii) -> None:
    u2 = u * math.cos(beta) - v * math.sin(beta)
    v2 = u * math.sin(beta) + v * math.cos(beta)
    point = [beta, u, v, u2, v2]
    slack = 1e-12  # the point's own rounding
    boxes = [(np.array([p - r - slack]), np.array([p + r + slack]))
             for p, r in zip(point, radii, strict=True)]
    with iv.quiet():
        raw = rot_contract_raw(*boxes)
    general = rot_contract(*boxes)
    for p, r, g in zip(point, raw, general, strict=True):
        assert r[0][0] <= p <= r[1][0]
        assert g[0][0] <= p <= g[1][0]
