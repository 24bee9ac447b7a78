"""Many predictions' LP bounds, one LP each along a nearest-neighbour path: every bound holds
each point of the relaxation the LPs found (their optima), is never looser than the box's own
bound, and equals lp_bounds' (each objective's LP solved on its own) to the LPs' tolerance;
the path visits every objective once."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from unittest import mock

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from calib_dsl.accuracy import batch_lp
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
    real = batch_lp.load
    with mock.patch.object(batch_lp, "load", lambda *a: _Counted(real(*a), runs)):
        lo, hi, _, settled = batch_bounds(rel, c, few)
    assert settled.all() and len(runs) == 4
    want_lo, want_hi = lp_bounds(rel, c, DEFAULT.tuned(lp__seconds=600.0).lp)
    scale = max(1.0, float(np.abs(want_hi - want_lo).max()))
    np.testing.assert_allclose([lo[0], hi[0]], [want_lo[0], want_hi[0]], atol=1e-6 * scale)
