"""Many predictions' LP bounds from a few LPs' multipliers: every bound holds each point of
the relaxation the LPs found (their optima), and is never looser than the box's own bound;
where every objective got its own LP, the bounds are lp_bounds'."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from calib_dsl.accuracy.batch_lp import batch_bounds
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


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 2 ** 31), st.integers(40, 400))
def test_bounds_hold_the_relaxations_points(seed, n):
    rel = relaxation()
    rng = np.random.default_rng(seed)
    base = rng.normal(size=(3, rel.main))
    # nearby objectives, as neighbouring poses give: a few directions, perturbed
    C = base[rng.integers(0, 3, n)] + 0.05 * rng.normal(size=(n, rel.main))
    few = replace(DEFAULT, prediction_first_lps=4, prediction_more_lps=4, prediction_rounds=3)
    lo, hi, optima = batch_bounds(rel, C, few)
    assert len(optima) > 0
    slack = 1e-7 * (1 + np.abs(C) @ np.max(np.abs(optima), axis=0))
    values = C @ optima.T  # (objectives, points): each point is feasible to HiGHS's tolerance
    assert np.all(values <= hi[:, None] + slack[:, None])
    assert np.all(values >= lo[:, None] - slack[:, None])
    pad = np.zeros(rel.A.shape[1] - rel.main)
    for c, a, b in zip(C[:20], lo, hi, strict=False):
        full = np.concatenate([c, pad])
        assert b <= box_max_up(full, full, rel.lo, rel.hi)
        assert -a <= box_max_up(-full, -full, rel.lo, rel.hi)


def test_every_objective_its_own_lp_is_lp_bounds():
    rel = relaxation()
    C = np.random.default_rng(7).normal(size=(12, rel.main))
    lo, hi, _ = batch_bounds(rel, C, replace(DEFAULT, prediction_first_lps=12))
    want_lo, want_hi = lp_bounds(rel, C)
    scale = np.maximum(1.0, np.abs(want_hi - want_lo))
    np.testing.assert_allclose(lo, want_lo, atol=1e-6 * scale.max())
    np.testing.assert_allclose(hi, want_hi, atol=1e-6 * scale.max())
