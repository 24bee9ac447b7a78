"""The inner bounds' point checks of the rows that can fail in their box only (inner/screen.py)
give what a check of every row gives: the same verdicts, failing rows and excesses, and for
a row left out (held over the whole box) an enclosure holding the point's."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import calib_dsl.analysis.certify_point as cp
from calib_dsl.inner import screen as sc
from calib_dsl.relax.layout import independents
from tests.relax.test_linearize import random_robot


def _readings(prog, rng, points):
    at = cp.reading_slots(prog)
    a, b = cp.exact_inside(prog.slots.lo[at], prog.slots.hi[at])
    a, b = np.where(a <= b, a, prog.slots.lo[at]), np.where(a <= b, b, prog.slots.hi[at])
    return np.clip(a + (b - a) * rng.random((points, len(at))), a, b)


@settings(max_examples=15, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 10_000), joints=st.integers(1, 3), rows=st.integers(5, 14),
       formulation=st.sampled_from(["matrix", "rotation"]), points=st.integers(1, 5),
       width=st.sampled_from([1e-9, 1e-7, 1e-5, 1e-3]))
def test_screened_checks_equal_every_rows(tmp_path_factory, seed, joints, rows, formulation,
                                          points, width):
    sim = random_robot(tmp_path_factory.mktemp("screen"), seed, joints, rows, formulation)
    prog = sim.prog
    if prog.rows is None:  # (a planar arm's shared measured side: unrolled)
        return
    rng = np.random.default_rng(seed)
    ind = independents(prog)
    dlo, dhi = prog.slots.lo[ind], prog.slots.hi[ind]
    half = width * (dhi - dlo)
    lo, hi = np.maximum(sim.p_true - half, dlo), np.minimum(sim.p_true + half, dhi)
    # the truth, the box's corners and points within: some fail, at rows the box can fail
    pts = lo + (hi - lo) * rng.random((points, len(ind)))
    pts[0] = np.clip(sim.p_true, lo, hi)
    if points > 1:
        pts[1] = np.where(rng.random(len(ind)) < 0.5, lo, hi)
    values = _readings(prog, rng, points)
    got = sc.checks(prog, (lo, hi), pts, values)
    whole = cp.check_points(prog, pts, values)
    scr = sc.screen(prog, lo, hi)
    for g, w in zip(got, whole, strict=True):
        assert g.holds == w.holds and g.in_domain == w.in_domain
        assert np.array_equal(g.slots, w.slots) and np.array_equal(g.ok, w.ok)
        assert np.array_equal(g.computed, w.computed)
        assert np.allclose(g.excess, w.excess, rtol=1e-12, atol=1e-12)
        if scr is None:
            continue
        # a row left out holds at the point in a check of every row (the screen's guard),
        # and its enclosure over the box holds the point's
        out = ~scr.mask
        assert np.all(w.ok[out]) and np.all(w.excess[out] == 0.0)
        assert np.all(g.lo[out] <= w.lo[out]) and np.all(w.hi[out] <= g.hi[out])


def test_a_point_outside_the_box_is_checked_on_every_row(tmp_path):
    sim = random_robot(tmp_path, 3, 2, 8, "matrix")
    prog = sim.prog
    ind = independents(prog)
    half = 1e-9 * (prog.slots.hi[ind] - prog.slots.lo[ind])
    lo, hi = sim.p_true - half, sim.p_true + half
    far = np.clip(sim.p_true + 1e3 * half, prog.slots.lo[ind], prog.slots.hi[ind])[None]
    values = _readings(prog, np.random.default_rng(0), 1)
    got, whole = sc.checks(prog, (lo, hi), far, values)[0], cp.check_points(prog, far, values)[0]
    assert got.holds == whole.holds
    assert np.array_equal(got.lo, whole.lo) and np.array_equal(got.hi, whole.hi)


def test_a_narrow_box_leaves_rows_out(tmp_path):
    # (the screen does something: near the truth, at a box far narrower than the data's
    # errors, most configurations hold over all of it)
    sim = random_robot(tmp_path, 5, 2, 12, "matrix")
    prog = sim.prog
    ind = independents(prog)
    half = 1e-9 * (prog.slots.hi[ind] - prog.slots.lo[ind])
    scr = sc.screen(prog, sim.p_true - half, sim.p_true + half)
    assert scr is not None and len(scr.rows) < len(prog.rows.rows)
    assert not scr.mask.all()
