"""Point checks of a large program a chunk of its rows at a time (certify_point.check_points
above CHUNK_CELLS) give what one pass over the whole program gives, rows in the same order
(the inner bounds compare two checks row by row: inner/bounds.py _pull_back), and the same
enclosures but for the last bits: an interval operation takes a faster path where every
element of its arrays allows (all positive factors of a product), and its other path may
round an element a little further out, so which rows share a pass moves a bound by an ulp
or two, always outward."""

from __future__ import annotations

from unittest import mock

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import calib_dsl.analysis.certify_point as cp
from calib_dsl.compile.chunks import Chunk, chunked
from calib_dsl.relax.layout import independents
from tests.relax.test_linearize import random_robot


def check_cells(n: int):
    """Chunked passes of about n slots x points while the block runs."""
    return mock.patch.object(cp, "CHUNK_CELLS", n)


def _fields(c: cp.PointCheck) -> list[np.ndarray]:
    assert c.ok is not None and c.computed is not None and c.side is not None
    return [c.slots, c.lo, c.hi, c.excess, c.ok, c.computed, c.side[0], c.side[1],
            np.array([c.holds, c.in_domain]),
            np.zeros(0, dtype=np.int64) if c.owner is None else c.owner]


@settings(max_examples=12, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 10_000), joints=st.integers(1, 3), rows=st.integers(5, 14),
       formulation=st.sampled_from(["matrix", "rotation"]), points=st.integers(1, 4),
       per_chunk=st.integers(1, 3), readings=st.booleans(), owners=st.booleans())
def test_chunked_checks_equal_the_whole_programs(tmp_path_factory, seed, joints, rows,
                                                 formulation, points, per_chunk, readings,
                                                 owners):
    sim = random_robot(tmp_path_factory.mktemp("checks"), seed, joints, rows, formulation)
    prog = sim.prog
    if prog.rows is None:  # (a planar arm's shared measured side: unrolled)
        return
    rng = np.random.default_rng(seed)
    ind = independents(prog)
    lo, hi = prog.slots.lo[ind], prog.slots.hi[ind]
    # the truth among the points: its checks hold, the others' mostly fail somewhere
    pts = np.clip(sim.p_true + (hi - lo) * 0.02 * rng.standard_normal((points, len(ind))),
                  lo, hi)
    pts[0] = sim.p_true
    at = cp.reading_slots(prog)
    values = None
    if readings:
        a, b = cp.exact_inside(prog.slots.lo[at], prog.slots.hi[at])
        a, b = np.where(a <= b, a, prog.slots.lo[at]), np.where(a <= b, b, prog.slots.hi[at])
        values = np.clip(a + (b - a) * rng.random((points, len(at))), a, b)
    small = (prog.rows.shared + per_chunk * prog.rows.width) * points
    with check_cells(small):
        assert chunked(prog, small // points) is not None  # (the chunked path runs)
        parts = cp.check_points(prog, pts, values, owners)
    with check_cells(10**9):
        whole = cp.check_points(prog, pts, values, owners)
    assert len(parts) == len(whole) == points
    for p, w in zip(parts, whole, strict=True):
        assert p.holds == w.holds and p.in_domain == w.in_domain
        for x, y in zip(_fields(p), _fields(w), strict=True):
            assert x.dtype == y.dtype and x.shape == y.shape
            if x.dtype.kind == "f":  # (the same infinities and nans, the rest to a few ulps of
                # the sides: an excess is their difference)
                assert np.array_equal(np.isfinite(x), np.isfinite(y))
                assert np.array_equal(x[~np.isfinite(x)], y[~np.isfinite(y)], equal_nan=True)
                assert np.allclose(x[np.isfinite(x)], y[np.isfinite(y)], rtol=1e-12, atol=1e-12)
            else:
                assert np.array_equal(x, y)


def test_a_padded_chunk_with_a_gap_is_not_read_as_a_slice():
    """Rows 0-8 and 10-23, padded with a copy of 23: as many entries as rows 0-23, but not
    those rows (a slice would read row 9's slots for row 10's)."""
    rows = np.concatenate([np.arange(9), np.arange(10, 24), [23]])
    assert Chunk(None, rows, None, True, 23).span is None
    assert Chunk(None, np.arange(3, 27), None, True, 24).span == slice(3, 27)
