"""The inner intervals' ends evaluated a few loop rows at a time, each row at only the points
it picked (accuracy/certified.py inner_at): the same enclosures as one pass of every point
over the whole program (inner_hull) within rounding, whatever the block of rows, and each
end the prediction at the point it names."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib_dsl.accuracy import certified
from calib_dsl.accuracy.certified import inner_at, inner_hull, picks
from calib_dsl.analysis.certify_point import check_points
from calib_dsl.elaborate.elaborator import Inputs
from calib_dsl.pipeline import load
from calib_dsl.relax.layout import independents

EXAMPLES = Path(__file__).resolve().parents[2] / "models" / "examples"


def _program(tmp: Path, rng: np.random.Generator, rows: int):
    for name in ("planar_arm.cal", "planar_arm_robot.cal"):
        shutil.copy(EXAMPLES / name, tmp)
    q = rng.uniform(-np.pi, np.pi, (rows, 2))
    body = "\n".join(f"{float(a)!r},{float(b)!r},0,0" for a, b in q)
    (tmp / "m.csv").write_text("q1,q2,x,y\n" + body + "\n")
    return load(tmp / "planar_arm.cal", inputs=Inputs(data={"m": tmp / "m.csv"},
                                                       consts={"e": "0.02"}))


@settings(max_examples=15, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.integers(0, 2 ** 31), st.integers(1, 9), st.integers(1, 6), st.integers(3, 12))
def test_picked_points_rows_at_a_time_match_every_point_in_one_pass(tmp_path, seed, block,
                                                                    npoints, rows):
    rng = np.random.default_rng(seed)
    prog = _program(tmp_path, rng, rows)
    ind = independents(prog)
    lo, hi = prog.slots.lo[ind], prog.slots.hi[ind]
    points = lo + (hi - lo) * rng.uniform(0.2, 0.8, (npoints, len(ind)))
    whole_lo, whole_hi, targets = inner_hull(prog, list(points))
    # every point picked by every row: the same intervals as inner_hull's
    every = np.tile(np.arange(npoints), (len(targets), 1))
    got_lo, got_hi, ends, _ = inner_at(prog, points, targets, every, block)
    # (a block's program rounds its own way: both enclosures hold, an ulp or so apart)
    np.testing.assert_allclose(got_lo, whole_lo, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(got_hi, whole_hi, rtol=1e-14, atol=1e-14)
    # some points picked per row: each end is that row's enclosure at the point it names
    some = rng.integers(0, npoints, (len(targets), 2))
    got_lo, got_hi, ends, _ = inner_at(prog, points, targets, some, block)
    checks = check_points(prog, points)
    where = {int(t): i for i, t in enumerate(checks[0].slots)}
    pos = np.array([where[int(t)] for t in targets])
    ok = ~np.isnan(got_lo)
    # (each end one of its own row's two picks, not another row's)
    own = (ends[ok] == some[ok][:, :1]) | (ends[ok] == some[ok][:, 1:])
    assert np.all(own) and np.all(ends[~ok] == -1)
    for i in np.flatnonzero(ok):
        # (the upper end of its enclosure)
        assert abs(got_lo[i] - checks[ends[i, 0]].hi[pos[i]]) <= 1e-14 * (1 + abs(got_lo[i]))
        assert abs(got_hi[i] - checks[ends[i, 1]].lo[pos[i]]) <= 1e-14 * (1 + abs(got_hi[i]))
        assert got_lo[i] <= got_hi[i]


def test_picks_are_each_rows_largest_and_smallest():
    rng = np.random.default_rng(3)
    W = rng.normal(size=(40, 3))
    points = rng.normal(size=(100, 3))  # more than one block of the picks' steps
    got = picks(lambda P: W @ P.T, points)
    values = W @ points.T
    np.testing.assert_array_equal(got[:, 0], values.argmax(axis=1))
    np.testing.assert_array_equal(got[:, 1], values.argmin(axis=1))


def test_blocks_shared_among_threads_give_the_serial_pass(tmp_path, monkeypatch):
    """More blocks than are evaluated at once, shared among threads: the same intervals,
    ends and readings as the blocks one after another in this thread."""
    rng = np.random.default_rng(11)
    prog = _program(tmp_path, rng, 40)
    ind = independents(prog)
    lo, hi = prog.slots.lo[ind], prog.slots.hi[ind]
    points = lo + (hi - lo) * rng.uniform(0.2, 0.8, (5, len(ind)))
    targets = inner_hull(prog, list(points))[2]
    some = rng.integers(0, len(points), (len(targets), 2))
    threaded = inner_at(prog, points, targets, some, 1)
    monkeypatch.setattr(certified, "in_threads", lambda fn, items: [fn(x) for x in items])
    serial = inner_at(prog, points, targets, some, 1)
    for a, b in zip(threaded, serial, strict=True):
        np.testing.assert_array_equal(a, b)
