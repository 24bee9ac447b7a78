"""The inner bounds' point checks of the rows some point's second-order models leave open only
(inner/screen.py, analysis/row_screen.screened_checks) give what a check of every row gives:
the same verdicts, failing rows and excesses, and for a row left out (proven at every point)
an enclosure holding the point's. A screen that admits a row that does not hold fails the
property (test_a_screen_admitting_a_failing_row_is_caught)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import calib_dsl.analysis.certify_point as cp
import calib_dsl.analysis.row_screen as rs
from calib_dsl.inner import screen as sc
from calib_dsl.relax.layout import independents
from tests.analysis.test_row_screen import _line, _middles
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
    _same(rs.row_screen(prog, lo, hi), pts, got, whole)


def _same(scr, pts, got, whole) -> None:
    """The screened checks `got` give the whole checks' verdicts, failing rows and
    excesses; a row left out held in the whole check, its enclosure holding the point's."""
    for g, w in zip(got, whole, strict=True):
        assert g.holds == w.holds and g.in_domain == w.in_domain
        assert np.array_equal(g.slots, w.slots) and np.array_equal(g.ok, w.ok)
        assert np.array_equal(g.computed, w.computed)
        assert np.allclose(g.excess, w.excess, rtol=1e-12, atol=1e-12)
    if scr is None or not np.all((pts >= scr.lo) & (pts <= scr.hi)):
        return
    # a row no point's models leave open was not evaluated: it held in the whole check,
    # and its enclosure (the box's) holds the point's
    need = rs._needs(scr, pts)[0][:, :-1].any(axis=0)
    out = (scr.whole_config >= 0) & ~need[np.maximum(scr.whole_config, 0)]
    for g, w in zip(got, whole, strict=True):
        assert np.all(w.ok[out]) and np.all(w.excess[out] == 0.0)
        assert np.all(g.lo[out] <= w.lo[out]) and np.all(w.hi[out] <= g.hi[out])


def test_a_screen_admitting_a_failing_row_is_caught(tmp_path):
    # row 2 (y = 1.05 +- 0.01) fails at a = 1, b = 0. The true screen leaves it open and
    # it is evaluated; a screen whose targets were widened admits it, and the comparison
    # with the whole check (the property above) must fail
    prog = _line(tmp_path, "1,1\n1,1\n1,1.05\n1,1\n")
    lo, hi = np.array([0.9, -0.1]), np.array([1.1, 0.1])
    pts, values = np.array([[1.0, 0.0]]), _middles(prog, 1)
    whole = cp.check_points(prog, pts, values)
    assert not whole[0].holds
    scr = rs.row_screen(prog, lo, hi)
    assert scr is not None
    _same(scr, pts, rs.screened_checks(scr, pts, values), whole)
    n = len(scr.inside[0])
    loose = replace(scr, inside=(np.full(n, -np.inf), np.full(n, np.inf)))
    got = rs.screened_checks(loose, pts, values)
    assert got[0].holds  # (admitted without evaluating row 2)
    with pytest.raises(AssertionError):
        _same(loose, pts, got, whole)


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
    scr = rs.row_screen(prog, sim.p_true - half, sim.p_true + half)
    assert scr is not None
    need = rs._needs(scr, sim.p_true[None])[0][:, :-1]
    assert not need.all()
