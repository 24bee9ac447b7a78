"""quadratic_readings.py: second-order rows with the readings' errors as LP columns.

- The relaxation holds at the true solution: (t, the products t_i t_j, each reading's error
  from its midpoint) satisfies every row and every column bound, on random robots (joint
  readings of three sizes) and on random expression programs whose rows mix the readings of
  two configurations (such rows are left out, or the truth would fail them), over random
  boxes around the truth.
- Its certified LP bounds hold the true values, also narrowed to themselves.
- On the RX90's 33 parameters it narrows what the first-order rounds leave (the reason it
  exists), and a model without readings gets none.
- End to end, tight solves of random robots with those rounds forced hold the truth (the
  rounds' bookkeeping: the narrowed columns, the map back to the box, their own multipliers).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from relax.test_chunked import chunk_count
from relax.test_linearize import (  # the sibling test modules: model generators, checks
    build_random_model,
    clean_version,
    random_box,
    robot_source,
    simulate_cal,
    truth_arrays,
)
from relax.test_taylor import assert_holds_truth

from calib_dsl.compile.group import compile_model
from calib_dsl.elaborate.elaborator import elaborate
from calib_dsl.ir.program import Program
from calib_dsl.lp.bounds import lp_bounds
from calib_dsl.relax.layout import independents
from calib_dsl.relax.quadratic import to_box
from calib_dsl.relax.quadratic_readings import relax_quadratic_readings
from calib_dsl.settings import LPSettings

ROOT = Path(__file__).resolve().parents[2]
SUPPORTED_OPS = ("neg", "sqr", "add", "sub", "mul", "sin", "cos")


def true_columns(prog: Program, lo: np.ndarray, hi: np.ndarray, rel, ex, p_true: np.ndarray,
                 cell_true: dict[int, float]) -> np.ndarray | None:
    """The truth in the relaxation's columns: t, the kept products, the readings' errors
    from the box's midpoints (None where a reading's true value is not known)."""
    n, kept = rel.main, ex.kept
    t = (p_true - ex.center) / ex.half
    products = (t[ex.pairs.i] * t[ex.pairs.j])[kept]
    s = prog.slots
    width = int(s.cell_col.max()) + 1
    ids = rel.col_keys[n + len(kept):] - n - len(ex.pairs.i)
    slot_of = {(int(s.cell_row[k]), int(s.cell_col[k])): k for k in cell_true}
    errors = []
    for row, col in zip(ids // width, ids % width, strict=True):
        slot = slot_of.get((int(row), int(col)))
        if slot is None:
            return None
        errors.append(cell_true[slot] - 0.5 * (lo[slot] + hi[slot]))
    return np.concatenate([t, products, np.array(errors)])


def check_readings(prog: Program, lo: np.ndarray, hi: np.ndarray, p_true: np.ndarray,
                   cell_true: dict[int, float], what: str, bounds: bool = True) -> bool:
    """The truth satisfies every row and column bound; the certified bounds hold it.
    False where there is no such relaxation (or a reading's truth is unknown)."""
    ind = independents(prog)
    assert np.all(lo[ind] <= p_true) and np.all(p_true <= hi[ind]), "bad test: p not in box"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        for mccormick in (False, True):
            out = relax_quadratic_readings(prog, lo, hi, mccormick=mccormick)
            if out is None:
                return False
            rel, ex = out
            z = true_columns(prog, lo, hi, rel, ex, p_true, cell_true)
            if z is None:
                return False
            assert_holds_truth(rel, ex, z, p_true, (what, mccormick), bounds and not mccormick,
                               lp=LPSettings(iterations=20000, seconds=30.0))
    return True


@pytest.mark.slow
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31 - 1), joints=st.integers(1, 3), rows=st.integers(1, 6),
       spatial=st.booleans(), formulation=st.sampled_from(["matrix", "rotation"]),
       tol_q=st.sampled_from([1e-6, 1e-4, 0.01]))
def test_the_relaxation_holds_the_truth_on_random_robots(tmp_path_factory, seed, joints, rows,
                                                          spatial, formulation, tol_q):
    rng = np.random.default_rng(seed)
    source = robot_source(rng, joints, tol_q, 1e-4, spatial)
    sim = simulate_cal(tmp_path_factory.mktemp("robot"), source, clean_version(source), rows,
                       seed, formulation)
    built = [check_readings(sim.prog, *random_box(rng, sim.prog, sim.p_true, sim.cell_true,
                                                  trial >= 1),
                            sim.p_true, sim.cell_true, f"box {trial}", bounds=trial == 0)
             for trial in range(3)]
    assert any(built), "the robot's joint readings give no relaxation"


@pytest.mark.slow
@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(seed=st.integers(0, 2**32 - 1), n_p=st.integers(1, 4), n_cfg=st.integers(1, 3),
       n_con=st.integers(1, 5), depth=st.integers(1, 4), models=st.integers(1, 6))
def test_the_relaxation_holds_the_truth_where_rows_mix_configurations(seed, n_p, n_cfg, n_con,
                                                                      depth, models):
    built = build_random_model(seed, n_p, n_cfg, 2, n_con, depth, ops=SUPPORTED_OPS,
                               models=models)
    assume(built is not None)
    prog, m = built
    p_true, cell_true = truth_arrays(prog, m)
    rng = np.random.default_rng(seed)
    for trial in range(3):
        lo, hi = random_box(rng, prog, p_true, cell_true, trial >= 1)
        check_readings(prog, lo, hi, p_true, cell_true, f"trial {trial}")


@pytest.mark.slow
def test_rx90_33_parameters_narrow_past_the_first_order_fixed_point() -> None:
    """rx90_recalibrate.cal from the box the first-order rounds end on (their fixed point,
    7 % wider than the hull): one round of these LPs narrows every identifiable parameter,
    and holds the truth."""

    from calib_dsl.settings import DEFAULT
    from calib_dsl.strategy.tight import solve_tight

    prog = compile_model(elaborate(ROOT / "models" / "rx90_recalibrate.cal"))
    first = solve_tight(prog, settings=DEFAULT.tuned(remainder_readings=1.0))
    assert first.status == "contracted"
    ind = independents(prog)
    p_true = np.array([prog.true_values[prog.slots.names[i]] for i in ind])
    out = relax_quadratic_readings(prog, first.lo, first.hi)
    assert out is not None
    rel, ex = out
    tl, th = lp_bounds(rel, np.eye(len(ind)), LPSettings(iterations=20000, seconds=30.0))
    plo, phi = to_box(ex, tl, th)
    assert np.all(plo <= p_true) and np.all(p_true <= phi)
    before = first.hi[ind] - first.lo[ind]
    after = np.minimum(phi, first.hi[ind]) - np.maximum(plo, first.lo[ind])
    seen = before < 0.99 * (prog.slots.hi[ind] - prog.slots.lo[ind])  # (not r2, r3)
    assert np.all(after[seen] < 0.97 * before[seen]), (after / before)[seen]


def test_a_model_without_readings_gets_none(tmp_path) -> None:
    src = ("param a in [0, 2];\nparam b in [-1, 1];\n"
           "sqr(a) + b == 1 +- 0.01;\na * b == 0.2 +- 0.01;\n")
    path = tmp_path / "m.cal"
    path.write_text(src, encoding="utf-8")
    prog = compile_model(elaborate(path))
    assert relax_quadratic_readings(prog, prog.slots.lo.copy(), prog.slots.hi.copy()) is None


@pytest.mark.slow
@pytest.mark.parametrize("after_mccormick", [False, True])
def test_solves_with_the_readings_rounds_hold_the_truth(tmp_path_factory, after_mccormick):
    """Whole tight solves of random robots (joint readings of three sizes), the fine rounds
    with the readings as LP columns forced wherever a model allows them (any remainder
    share), from the start or after McCormick's fine rounds (then with McCormick's
    inequalities too, whatever the remainders cost): the result holds the truth every time,
    and those rounds ran in most solves."""

    from calib_dsl.settings import DEFAULT
    from calib_dsl.strategy.tight import solve_tight

    forced = (DEFAULT.tuned(remainder_readings=0.0, remainder_wide=0.0, readings_cost=0.0,
                      fine_min_gain=1.0) if after_mccormick
              else DEFAULT.tuned(remainder_readings=0.0, remainder_wide=2.0))
    rng = np.random.default_rng(2026)
    ran = 0
    for trial in range(12):
        seed = int(rng.integers(2**31))
        source = robot_source(rng, int(rng.integers(1, 4)), float(rng.choice([1e-6, 1e-4, 0.01])),
                              1e-4, bool(rng.integers(2)))
        sim = simulate_cal(tmp_path_factory.mktemp("robot"), source, clean_version(source),
                           int(rng.integers(2, 7)), seed,
                           str(rng.choice(["matrix", "rotation"])))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            res = solve_tight(sim.prog, settings=forced)
        ind = independents(sim.prog)
        assert res.status == "contracted", trial
        assert np.all(res.lo[ind] <= sim.p_true) and np.all(sim.p_true <= res.hi[ind]), trial
        assert res.history is not None
        labels = [s.label for s in res.history.steps]
        this = any("readings as LP columns" in label for label in labels)
        ran += this
        if after_mccormick and this:  # (McCormick's rounds first)
            first = next(k for k, label in enumerate(labels) if "readings" in label)
            assert "(second order" in labels[first - 1], labels
    assert ran >= 6, ran


@pytest.mark.slow
@settings(max_examples=12, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 2**31 - 1), joints=st.integers(1, 3), rows=st.integers(5, 10),
       formulation=st.sampled_from(["matrix", "rotation"]), mccormick=st.booleans())
def test_chunks_give_the_whole_programs_relaxation(tmp_path_factory, monkeypatch, seed, joints,
                                                  rows, formulation, mccormick):
    """Relaxed two rows at a time (compile/chunks.py), the relaxation has the whole one's
    rows and columns (matched by target slot and by cell), with the same keys, holds the
    truth, and certifies the same bounds; its rows are numbered as relax_quadratic numbers
    the same chunks (the row keys a later LP starts from)."""
    import calib_dsl.relax.quadratic_readings as qr
    import calib_dsl.relax.taylor as taylor
    from calib_dsl.relax.quadratic import relax_quadratic

    rng = np.random.default_rng(seed)
    source = robot_source(rng, joints, 1e-4, 1e-4, True)
    sim = simulate_cal(tmp_path_factory.mktemp("robot"), source, clean_version(source), rows,
                       seed, formulation)
    prog = sim.prog
    assume(prog.rows is not None)
    lo, hi = random_box(rng, prog, sim.p_true, sim.cell_true, False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        whole = relax_quadratic_readings(prog, lo, hi, mccormick=mccormick)
        small = prog.rows.shared + 2 * prog.rows.width
        monkeypatch.setattr(qr, "CHUNK_SLOTS", small)
        monkeypatch.setattr(taylor, "CHUNK_SLOTS", small)
        assert len(qr.chunked(prog, small, None) or []) == chunk_count((rows + 1) // 2, rows)
        parts = relax_quadratic_readings(prog, lo, hi, mccormick=mccormick)
        plain = relax_quadratic(prog, lo, hi, prune=0.0, mccormick=mccormick)
    assume(whole is not None)
    assert parts is not None and plain is not None
    (rw, _), (rp, ep) = whole, parts
    assert rw.A.shape == rp.A.shape and sorted(rw.col_keys) == sorted(rp.col_keys)
    rows_of = [sorted(r.targets[r.targets >= 0]) for r in (rw, rp)]
    assert rows_of[0] == rows_of[1]
    assert sorted(rw.keys) == sorted(rp.keys)
    z = true_columns(prog, lo, hi, rp, ep, sim.p_true, sim.cell_true)
    assert z is not None
    assert_holds_truth(rp, ep, z, sim.p_true, "chunks", False)
    n = rw.main
    bw, bp = lp_bounds(rw, np.eye(n)), lp_bounds(rp, np.eye(n))
    assert np.allclose(bw[0], bp[0], atol=1e-7) and np.allclose(bw[1], bp[1], atol=1e-7)
    # the same key means the same constraint in both second-order families
    rq = plain[0]
    at = {int(k): int(t) for k, t in zip(rq.keys, rq.targets, strict=True) if t >= 0}
    for k, t in zip(rp.keys, rp.targets, strict=True):
        assert t < 0 or at.get(int(k)) == int(t)


def _with_gradients(monkeypatch) -> None:
    """quadratic_readings' first-order pass with the gradient in the unknowns as well (at
    the box's centre), as it was made before it computed the readings' part alone."""
    import calib_dsl.relax.quadratic_readings as qr

    plain = qr.Evaluation

    def evaluation(prog, lo, hi, ind, centre):
        ind = independents(prog)
        return plain(prog, lo, hi, ind, 0.5 * lo[ind] + 0.5 * hi[ind])

    monkeypatch.setattr(qr, "Evaluation", evaluation)


def assert_same_relaxation(a, b) -> None:
    """Two relaxations with the same bits: rows, sides, columns and keys."""
    assert (a is None) == (b is None)
    if a is None:
        return
    (ra, ea), (rb, eb) = a, b
    for name in ("b", "b_lo", "lo", "hi", "keys", "targets", "col_keys", "slack"):
        x, y = getattr(ra, name), getattr(rb, name)
        assert (x is None) == (y is None), name
        if x is not None:
            assert np.array_equal(x, y, equal_nan=True), name
    assert ra.A.shape == rb.A.shape
    for name in ("data", "indices", "indptr"):
        assert np.array_equal(getattr(ra.A, name), getattr(rb.A, name), equal_nan=True), name
    assert np.array_equal(ea.kept, eb.kept)


@settings(max_examples=30, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much,
                                 HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 2**32 - 1), n_p=st.integers(1, 4), n_cfg=st.integers(1, 3),
       n_con=st.integers(1, 5), depth=st.integers(1, 4), models=st.integers(1, 6),
       mccormick=st.booleans())
def test_readings_alone_give_the_same_relaxation(monkeypatch, seed, n_p, n_cfg, n_con, depth,
                                                 models, mccormick):
    """The first-order pass computes the readings' derivatives without the gradient in the
    unknowns: the relaxation is the same, bit for bit, as with it, on random programs whose
    rows mix configurations, over random boxes around the truth."""
    built = build_random_model(seed, n_p, n_cfg, 2, n_con, depth, ops=SUPPORTED_OPS,
                               models=models)
    assume(built is not None)
    prog, m = built
    p_true, cell_true = truth_arrays(prog, m)
    rng = np.random.default_rng(seed)
    for trial in range(3):
        lo, hi = random_box(rng, prog, p_true, cell_true, trial >= 1)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            alone = relax_quadratic_readings(prog, lo, hi, mccormick=mccormick)
            with monkeypatch.context() as mp:
                _with_gradients(mp)
                both = relax_quadratic_readings(prog, lo, hi, mccormick=mccormick)
        assert_same_relaxation(alone, both)
        if alone is not None:
            check_readings(prog, lo, hi, p_true, cell_true, f"trial {trial}", bounds=False)


@pytest.mark.slow
@settings(max_examples=6, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 2**31 - 1), joints=st.integers(1, 3), rows=st.integers(3, 6),
       formulation=st.sampled_from(["matrix", "rotation"]))
def test_readings_alone_give_the_same_relaxation_of_chunked_robots(
        tmp_path_factory, monkeypatch, seed, joints, rows, formulation):
    """The same on random robots relaxed two rows at a time (a chunk's program: the relaxed
    check's and a large campaign's path), and the truth satisfies it."""
    import calib_dsl.relax.quadratic_readings as qr
    import calib_dsl.relax.taylor as taylor

    rng = np.random.default_rng(seed)
    source = robot_source(rng, joints, 1e-4, 1e-4, True)
    sim = simulate_cal(tmp_path_factory.mktemp("robot"), source, clean_version(source), rows,
                       seed, formulation)
    prog = sim.prog
    assume(prog.rows is not None)
    lo, hi = random_box(rng, prog, sim.p_true, sim.cell_true, False)
    small = prog.rows.shared + 2 * prog.rows.width
    with monkeypatch.context() as mp, warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        mp.setattr(qr, "CHUNK_SLOTS", small)
        mp.setattr(taylor, "CHUNK_SLOTS", small)
        alone = qr.relax_quadratic_readings(prog, lo, hi)
        _with_gradients(mp)
        both = qr.relax_quadratic_readings(prog, lo, hi)
    assume(alone is not None)
    assert_same_relaxation(alone, both)
    rel, ex = alone
    z = true_columns(prog, lo, hi, rel, ex, sim.p_true, sim.cell_true)
    assert z is not None
    assert_holds_truth(rel, ex, z, sim.p_true, "readings alone", False)
