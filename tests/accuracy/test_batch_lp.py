"""Many predictions' LP bounds, one LP each along a nearest-neighbour path: every bound holds
each point of the relaxation the LPs found (their optima), is never looser than the box's own
bound, and equals lp_bounds' (each objective's LP solved on its own) to the LPs' tolerance;
the path visits every objective once."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from unittest import mock

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calib_dsl.accuracy import batch_lp, working_rows
from calib_dsl.accuracy.batch_lp import batch_bounds, path
from calib_dsl.lp.bounds import lp_bounds
from calib_dsl.lp.certify import box_max_up
from calib_dsl.pipeline import load, solve
from calib_dsl.relax.quadratic import relax_quadratic
from calib_dsl.settings import DEFAULT

ROOT = Path(__file__).resolve().parents[2]
_CACHE: dict[str, object] = {}


def relaxation():
    if "rel" not in _CACHE:
        prog = load(ROOT / "models" / "ur10_simulated.cal")
        sol = solve(prog)
        fine = relax_quadratic(prog, sol.lo, sol.hi, prune=0.0, mccormick=True)
        assert fine is not None
        _CACHE["rel"] = fine[0]
    return _CACHE["rel"]


@settings(max_examples=3, deadline=None)  # 10 in bench/checks/test_soundness_full.py
@given(st.integers(0, 2 ** 31), st.integers(12, 60))
def test_bounds_hold_the_relaxations_points(seed, n):
    rel = relaxation()
    rng = np.random.default_rng(seed)
    base = rng.normal(size=(3, rel.main))
    # nearby objectives, as neighbouring poses give: a few directions, perturbed
    C = base[rng.integers(0, 3, n)] + 0.05 * rng.normal(size=(n, rel.main))
    lo, hi, optima, _ = batch_bounds(rel, C, replace(DEFAULT, prediction_path_window=20))
    assert 0 < len(optima) <= 2 * n
    slack = 1e-7 * (1 + np.abs(C) @ np.max(np.abs(optima), axis=0))
    values = C @ optima.T  # (objectives, points): each point is feasible to HiGHS's tolerance
    assert np.all(values <= hi[:, None] + slack[:, None])
    assert np.all(values >= lo[:, None] - slack[:, None])
    pad = np.zeros(rel.A.shape[1] - rel.main)
    for c, a, b in zip(C[:20], lo, hi, strict=False):
        full = np.concatenate([c, pad])
        assert b <= box_max_up(full, full, rel.lo, rel.hi)
        assert -a <= box_max_up(-full, -full, rel.lo, rel.hi)


@settings(max_examples=1, deadline=None)  # 4 in bench/checks/test_soundness_full.py
@given(st.integers(0, 2 ** 31))
def test_the_path_bounds_are_lp_bounds(seed):
    rel = relaxation()
    rng = np.random.default_rng(seed)
    # nearby objectives (the path's case) and a few far apart
    base = rng.normal(size=(2, rel.main))
    C = np.concatenate([base[rng.integers(0, 2, 8)] + 0.02 * rng.normal(size=(8, rel.main)),
                        rng.normal(size=(2, rel.main))])
    # the pivot limit alone stops an LP (on a loaded host the time backstop would stop one
    # of the two early: a sound but wider bound)
    unhurried = DEFAULT.tuned(lp__seconds=600.0)
    lo, hi, _, _ = batch_bounds(rel, C, unhurried)
    want_lo, want_hi = lp_bounds(rel, C, unhurried.lp)
    scale = np.maximum(1.0, np.abs(want_hi - want_lo))
    np.testing.assert_allclose(lo, want_lo, atol=1e-6 * scale.max())
    np.testing.assert_allclose(hi, want_hi, atol=1e-6 * scale.max())


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2 ** 31), st.integers(1, 120), st.integers(1, 40))
def test_the_path_visits_each_objective_once_nearest_first(seed, n, window):
    rng = np.random.default_rng(seed)
    C = rng.normal(size=(n, 5))
    order = path(C, window)
    assert sorted(order.tolist()) == list(range(n))
    whole = path(C, n)  # one window: each step goes to the nearest one not visited yet
    U = C / np.linalg.norm(C, axis=1)[:, None]
    for k in range(1, n):
        left = whole[k:]
        assert U[whole[k]] @ U[whole[k - 1]] >= np.max(U[left] @ U[whole[k - 1]]) - 1e-12


class _Counted:
    """A HiGHS model that counts its runs."""

    def __init__(self, h, runs: list[int]) -> None:
        self._h, self._runs = h, runs

    def run(self):
        self._runs.append(1)
        return self._h.run()

    def __getattr__(self, name):
        return getattr(self._h, name)


@settings(max_examples=3, deadline=None)
@given(st.integers(0, 2 ** 31))
def test_an_lp_its_pivot_limit_stopped_is_run_once_more_with_every_runs_pivots(seed):
    # from no basis these LPs take 450-560 pivots: more than one run's 50, fewer than the
    # twelve runs' 600. HiGHS does not go on from a run its pivot limit stopped before it
    # found a feasible basis (another run repeats the same 50 pivots): one more run with
    # the raised limit ends each optimal, two runs a sign, not twelve
    rel = relaxation()
    rng = np.random.default_rng(seed)
    c = rng.normal(size=(1, rel.main))
    few = DEFAULT.tuned(lp__iterations=50, lp__seconds=600.0, prediction_lp_runs=12)
    runs: list[int] = []
    real = working_rows.load
    with mock.patch.object(working_rows, "load", lambda *a: _Counted(real(*a), runs)):
        lo, hi, _, settled = batch_bounds(rel, c, few)
    assert settled.all() and len(runs) == 4
    want_lo, want_hi = lp_bounds(rel, c, DEFAULT.tuned(lp__seconds=600.0).lp)
    scale = max(1.0, float(np.abs(want_hi - want_lo).max()))
    np.testing.assert_allclose([lo[0], hi[0]], [want_lo[0], want_hi[0]], atol=1e-6 * scale)


def _working_set_settings(keep: int, added: int):
    # a row leaves the model after `keep` LPs it was inactive at: small values make the path
    # run on few rows and re-add many; passes enough for any LP to end over every row (the
    # pivot limit alone stops an LP: no time backstop)
    return DEFAULT.tuned(lp__seconds=600.0, prediction_rows_kept=keep,
                         prediction_rows_added=added, prediction_row_passes=400,
                         prediction_path_window=40)


@pytest.mark.slow
@settings(max_examples=1, deadline=None)  # 4 in bench/checks/test_soundness_full.py
@given(st.integers(0, 2 ** 31), st.integers(0, 3), st.integers(3, 12))
def test_the_working_rows_bounds_are_the_all_rows_lps(seed, keep, added):
    # objectives in a few directions far apart: after each jump the optimum leaves the
    # rows the model kept, violates others, and only the check against every row brings
    # the bound down to the whole LP's (a working set's own optimum is a relaxation's)
    rel = relaxation()
    rng = np.random.default_rng(seed)
    base = rng.normal(size=(4, rel.main))
    C = base[rng.integers(0, 4, 24)] + 0.1 * rng.normal(size=(24, rel.main))
    lo, hi, _, settled = batch_bounds(rel, C, _working_set_settings(keep, added))
    want_lo, want_hi = lp_bounds(rel, C, DEFAULT.tuned(lp__seconds=600.0).lp)
    scale = np.maximum(1.0, np.abs(want_hi - want_lo)).max()
    assert settled.all()
    np.testing.assert_allclose(lo, want_lo, atol=1e-6 * scale)
    np.testing.assert_allclose(hi, want_hi, atol=1e-6 * scale)


def test_the_working_rows_leave_out_rows_the_optima_do_not_need():
    # the point of the working set: after a few LPs the model holds far fewer rows than
    # the relaxation (HiGHS's cost per run grows with them)
    rel = relaxation()
    rng = np.random.default_rng(7)
    C = rng.normal(size=(1, rel.main)) + 0.02 * rng.normal(size=(30, rel.main))
    sizes: list[int] = []
    real = batch_lp._run

    def counted(h, limits):
        sizes.append(h.getNumRow())
        return real(h, limits)

    with mock.patch.object(batch_lp, "_run", counted):
        batch_bounds(rel, C, _working_set_settings(2, 8))
    assert sizes[0] == rel.A.shape[0] and min(sizes[-10:]) < rel.A.shape[0] // 2


def test_a_row_that_keeps_coming_back_stays_in_the_model():
    # a path that cycles through three directions: each LP's optimum needs the rows the
    # model dropped since the last LP in its direction. A row dropped after `keep` LPs and
    # added back each time would cost every LP a run per row it adds back (about twenty
    # here); one kept `keep` LPs longer each time it came back soon stays, and the later
    # LPs end in one run (two where a row is new)
    rel = relaxation()
    rng = np.random.default_rng(3)
    base = rng.normal(size=(3, rel.main))
    C = base[np.arange(45) % 3] + 1e-3 * rng.normal(size=(45, rel.main))
    runs: list[int] = []
    real_run, real_solve = batch_lp._run, batch_lp._solve

    def counted_solve(*args):
        runs.append(0)
        return real_solve(*args)

    def counted_run(h, limits):
        runs[-1] += 1
        return real_run(h, limits)

    one = _working_set_settings(1, 8).tuned(lp__workers=1)
    with mock.patch.object(batch_lp, "_run", counted_run), \
            mock.patch.object(batch_lp, "_solve", counted_solve), \
            mock.patch.object(batch_lp, "path", lambda C, w: np.arange(len(C))):
        lo, hi, _, settled = batch_bounds(rel, C, one)
    assert settled.all()
    per_sign = len(runs) // 2
    assert max(runs[per_sign - 10:per_sign]) <= 2 and max(runs[-10:]) <= 2
    want_lo, want_hi = lp_bounds(rel, C, DEFAULT.tuned(lp__seconds=600.0).lp)
    scale = np.maximum(1.0, np.abs(want_hi - want_lo)).max()
    np.testing.assert_allclose(lo, want_lo, atol=1e-6 * scale)
    np.testing.assert_allclose(hi, want_hi, atol=1e-6 * scale)
