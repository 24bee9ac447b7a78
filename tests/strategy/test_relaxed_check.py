"""The working set's check on the relaxation's own rows (strategy/relaxed_check.py): a row
left out is reported where it cuts an LP optimum off whatever its own columns are, and the
rows it reports on a simulated campaign are outside the working set and cut the optima of
the working set's LPs off."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from calib_dsl.relax.relaxation import LinearRelaxation, Rows
from calib_dsl.strategy.relaxed_check import _excess, _excesses


@settings(max_examples=200, deadline=None)
@given(a=st.floats(-3, 3), c=st.floats(-3, 3), x=st.floats(-1, 1), b=st.floats(-5, 5),
       width=st.floats(0, 4))
def test_a_row_is_violated_only_where_no_free_value_satisfies_it(a, c, x, b, width):
    """Row: b - width <= a x + c z <= b, x known, z free in [-1, 1]: the excess is positive
    exactly where no z on a fine grid satisfies the row (by more than the grid's step)."""
    A = Rows(np.array([a, c]), np.array([0, 1]), np.array([0, 2]), (1, 2))
    rel = LinearRelaxation(A, np.array([b]), np.array([-1.0, -1.0]), np.array([1.0, 1.0]),
                           main=1, b_lo=np.array([b - width]))
    excess = _excess(rel, np.array([x, np.nan]))[0]
    values = a * x + c * np.linspace(-1, 1, 20001)
    gap = np.maximum(values - b, b - width - values).min()
    step, eps = 1e-4 * abs(c), 1e-9 * (1 + abs(a) + abs(b) + width)
    if gap > step:  # (then the grid's best is within a step of the row's best)
        assert abs(excess - gap) <= step + eps
    assert (excess > eps) <= (gap > 0)
    assert (gap > step + eps) <= (excess > 0)


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_points_checked_together_get_each_its_own_excess(seed):
    """Several points at once, some leaving the same columns unknown and some not: each
    point's excesses are those it gets alone."""
    rng = np.random.default_rng(seed)
    m, n = 12, 6
    dense = rng.normal(size=(m, n)) * (rng.random((m, n)) < 0.6)
    rows, cols = np.nonzero(dense)
    indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=m))])
    A = Rows(dense[rows, cols], cols, indptr, (m, n))
    b = rng.normal(size=m)
    rel = LinearRelaxation(A, b, -rng.random(n), rng.random(n), main=2,
                           b_lo=np.where(rng.random(m) < 0.3, -np.inf, b - rng.random(m)))
    X = rng.uniform(-1, 1, (5, n))
    X[:3, 4:] = np.nan  # three points of one LP
    X[3, rng.random(n) < 0.5] = np.nan
    together = _excesses(rel, X)
    for x, got in zip(X, together, strict=True):
        alone = _excess(rel, x)
        assert np.array_equal(np.isinf(alone), np.isinf(got))
        finite = np.isfinite(alone)
        assert np.allclose(alone[finite], got[finite], rtol=1e-12, atol=1e-12)


def test_the_rows_reported_on_a_campaign_are_left_out_and_cut_the_optima_off(tmp_path):
    from calib_dsl.compile.chunks import loop_rows, start_rows
    from calib_dsl.elaborate.elaborator import Inputs
    from calib_dsl.lp.certify import Certificates
    from calib_dsl.pipeline import load
    from calib_dsl.propagate.fixpoint import propagate
    from calib_dsl.settings import DEFAULT
    from calib_dsl.strategy.relaxed_check import violated_rows
    from calib_dsl.strategy.rounds import LPRounds
    from calib_dsl.studies.campaign import Campaign
    from calib_dsl.studies.simulate import simulate
    from tests.test_ur10 import TRACKER, _noisy_simulation_model

    table = tmp_path / "sim.csv"
    simulate(_noisy_simulation_model(tmp_path, 0.05), 80, 4, out_csv=table,
             campaign=Campaign("random", 4, systematic=0.6))
    prog = load(TRACKER, inputs=Inputs(data={"m": table}, consts={"e": "0.65"}))
    rows = start_rows(prog, 10)
    assert rows is not None
    res = propagate(prog, tol=1e-5, max_sweeps=100)
    fine = Certificates()
    LPRounds(prog, replace(DEFAULT), Certificates(), 1e-5, 100, DEFAULT.rounds.max_rounds, True,
             rows=rows, fine_certs=fine).contract(res.lo, res.hi)
    outside = np.setdiff1d(np.arange(loop_rows(prog)), rows)
    found = violated_rows(prog, fine, outside)
    assert found is not None and len(found) == len(fine.columns)
    reported = np.concatenate([r for r, _ in found])
    assert len(reported) > 0  # (10 rows of 80 leave the LPs' optima where others cut them)
    assert np.all(np.isin(reported, outside))
    assert all(np.all(excess > 0) for _, excess in found)


def test_the_rows_checked_a_chunk_at_a_time_are_those_of_one_relaxation(tmp_path,
                                                                       monkeypatch):
    """The check relaxes the rows left out a chunk at a time (its memory follows the
    chunk): on a campaign, chunks of one row and one relaxation of every row report the same
    rows with the same excesses, for every optimum."""
    from calib_dsl.compile.chunks import loop_rows, start_rows
    from calib_dsl.elaborate.elaborator import Inputs
    from calib_dsl.lp.certify import Certificates
    from calib_dsl.pipeline import load
    from calib_dsl.propagate.fixpoint import propagate
    from calib_dsl.settings import DEFAULT
    from calib_dsl.strategy import relaxed_check
    from calib_dsl.strategy.rounds import LPRounds
    from calib_dsl.studies.campaign import Campaign
    from calib_dsl.studies.simulate import simulate
    from tests.test_ur10 import TRACKER, _noisy_simulation_model

    table = tmp_path / "sim.csv"
    simulate(_noisy_simulation_model(tmp_path, 0.05), 40, 5, out_csv=table,
             campaign=Campaign("random", 5, systematic=0.6))
    prog = load(TRACKER, inputs=Inputs(data={"m": table}, consts={"e": "0.65"}))
    rows = start_rows(prog, 8)
    assert rows is not None and prog.rows is not None
    res = propagate(prog, tol=1e-5, max_sweeps=100)
    fine = Certificates()
    LPRounds(prog, replace(DEFAULT), Certificates(), 1e-5, 100, DEFAULT.rounds.max_rounds, True,
             rows=rows, fine_certs=fine).contract(res.lo, res.hi)
    outside = np.setdiff1d(np.arange(loop_rows(prog)), rows)
    monkeypatch.setattr(relaxed_check, "CHUNK_SLOTS", 10**9)
    whole = relaxed_check.violated_rows(prog, fine, outside)
    monkeypatch.setattr(relaxed_check, "CHUNK_SLOTS", prog.rows.shared + prog.rows.width)
    parts = relaxed_check.violated_rows(prog, fine, outside)
    # the chunks shared among threads: the same rows and excesses in the same order
    shared = relaxed_check.violated_rows(prog, fine, outside, workers=2)
    assert shared is not None and parts is not None
    for (r1, e1), (r2, e2) in zip(parts, shared, strict=True):
        assert np.array_equal(r1, r2) and np.array_equal(e1, e2)
    assert whole is not None and len(whole) == len(parts)
    assert sum(len(r) for r, _ in whole) > 0
    for (r1, e1), (r2, e2) in zip(whole, parts, strict=True):
        a, b = np.lexsort((e1, r1)), np.lexsort((e2, r2))
        assert np.array_equal(r1[a], r2[b])
        assert np.allclose(e1[a], e2[b], rtol=1e-12, atol=0.0)
