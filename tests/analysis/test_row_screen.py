"""The screened point check (analysis/row_screen.py) gives check_points' verdict (with
prove_point's where only rows comparing two computed values fail) while evaluating only the
rows the second-order bound leaves open; each rule that skips an evaluation has a test that
fails without its guard."""

from __future__ import annotations

from pathlib import Path
from unittest import mock

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import calib_dsl.analysis.row_screen as rs
import calib_dsl.relax.taylor as taylor
from calib_dsl.analysis.certify_point import check_points, exact_inside, reading_slots
from calib_dsl.analysis.existence import prove_point
from calib_dsl.pipeline import load
from calib_dsl.relax.layout import independents
from calib_dsl.relax.models import Models, Pairs
from calib_dsl.relax.taylor import Constraints, Expansion
from tests.relax.test_linearize import random_robot

LINE = """param a in [0, 2] true 1;
param b in [-1, 1] true 0;
table m = "pts.csv" {
  x : +- 1e-6;
  y : +- 0.01;
}
for k in 1..rows(m) {
  a * m.x[k] + b == m.y[k];
}
a - b == [0.9, 1.1];
"""


def _full(prog, points, readings) -> np.ndarray:
    checks = check_points(prog, points, readings)
    return np.array([c.holds or prove_point(prog, p, r, c)
                     for p, r, c in zip(points, readings, checks, strict=True)])


def _middles(prog, k: int) -> np.ndarray:
    at = reading_slots(prog)
    return np.tile(0.5 * prog.slots.lo[at] + 0.5 * prog.slots.hi[at], (k, 1))


@settings(max_examples=10, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 10_000), joints=st.integers(1, 3), rows=st.integers(5, 12),
       formulation=st.sampled_from(["matrix", "rotation"]), spread=st.floats(1e-4, 0.05),
       most_open=st.sampled_from([0.0, 0.15, 1.0]))
def test_screened_verdicts_equal_the_whole_checks(tmp_path_factory, seed, joints, rows,
                                                  formulation, spread, most_open):
    # (most_open 0: every pass the whole check; 1: one-row chunks however many are open)
    sim = random_robot(tmp_path_factory.mktemp("screen"), seed, joints, rows, formulation)
    prog = sim.prog
    ind = independents(prog)
    dlo, dhi = prog.slots.lo[ind], prog.slots.hi[ind]
    rng = np.random.default_rng(seed)
    width = (dhi - dlo) * spread
    lo, hi = np.maximum(sim.p_true - width, dlo), np.minimum(sim.p_true + width, dhi)
    screen = rs.row_screen(prog, lo, hi, most_open)
    if screen is None:
        return
    # points in the box (the truth among them), and some beyond it
    pts = np.clip(sim.p_true + width * rng.uniform(-1.5, 1.5, (12, len(ind))), dlo, dhi)
    pts[0] = sim.p_true
    at = reading_slots(prog)
    a, b = exact_inside(prog.slots.lo[at], prog.slots.hi[at])
    a, b = np.where(a <= b, a, prog.slots.lo[at]), np.where(a <= b, b, prog.slots.hi[at])
    readings = np.clip(a + (b - a) * rng.random((len(pts), len(at))), a, b)
    readings[:6] = _middles(prog, 6)
    assert np.array_equal(rs.screened_holds(screen, pts, readings),
                          _full(prog, pts, readings))


def _line(tmp: Path, rows: str = "1,1\n1,1\n1,1\n1,1\n", shared: str = ""):
    text = LINE.replace("a - b == [0.9, 1.1];", shared) if shared else LINE
    (tmp / "line.cal").write_text(text, encoding="utf-8")
    (tmp / "pts.csv").write_text("x,y\n" + rows, encoding="utf-8")
    prog = load(tmp / "line.cal")
    assert prog.rows is not None  # (a loop compiled once: the screen's case)
    return prog


def test_the_screen_proves_rows_and_skips_their_evaluation(tmp_path):
    prog = _line(tmp_path)
    screen = rs.row_screen(prog, np.array([0.9, -0.05]), np.array([1.05, 0.05]))
    assert screen is not None
    pts = np.array([[1.0, 0.0], [0.99, 0.005]])
    need, false = rs._needs(screen, pts)
    assert not need.any() and not false.any()  # every row, the shared one too, proven
    with mock.patch.object(rs, "check_points", side_effect=AssertionError("evaluated")):
        assert rs.screened_holds(screen, pts, _middles(prog, 2)).all()


def test_a_shared_row_left_open_is_evaluated(tmp_path):
    # a = 0.8, b = 0.2 fits every row of the loop (a + b = 1) but misses sin(a) - b in
    # [0.52, 0.6] by 0.003, less than its model's third-order remainder over the box: the
    # loop's rows are proven, the shared row is left open, and only a chunk evaluates it
    prog = _line(tmp_path, shared="sin(a) - b == [0.52, 0.6];")
    screen = rs.row_screen(prog, np.array([0.5, -0.1]), np.array([1.1, 0.5]))
    assert screen is not None
    pts = np.array([[0.8, 0.2], [0.82, 0.18]])
    need, false = rs._needs(screen, pts)
    assert need[0, -1] and not need[0, :-1].any() and not false.any()
    readings = _middles(prog, 2)
    assert list(rs.screened_holds(screen, pts, readings)) == [False, True]
    assert list(_full(prog, pts, readings)) == [False, True]


def test_a_point_outside_the_models_box_is_evaluated_on_every_row(tmp_path):
    # the models hold on their box only: a point beyond it (here a + b = 1.3, every loop
    # row false) would be read at the box's edge, where every row holds, without the guard
    prog = _line(tmp_path)
    screen = rs.row_screen(prog, np.array([0.95, -0.05]), np.array([1.05, 0.05]))
    assert screen is not None
    pts = np.array([[1.15, 0.15]])
    assert rs._needs(screen, pts)[0][0, :-1].all()
    assert not rs.screened_holds(screen, pts, _middles(prog, 1))[0]


def test_a_row_no_model_covers_is_always_evaluated(tmp_path):
    # the models of loop row 2 left out (as a capped temporary or a row comparing two
    # computed values has none): that row is evaluated at every point. Its y is 1.05, so
    # a = 1, b = 0 misses it by 0.05 > 0.01, and only its evaluation finds it.
    prog = _line(tmp_path, "1,1\n1,1\n1,1.05\n1,1\n")
    lay = prog.rows
    assert lay is not None
    real = rs.expand

    def without_row_2(p, lo, hi, **options):
        ex = real(p, lo, hi, **options)
        keep = np.flatnonzero((ex.rows.slots - lay.shared) // lay.width != 2)
        return Expansion(ex.center, ex.half, ex.pairs, ex.rows.take(keep))

    with mock.patch.object(rs, "expand", without_row_2):
        screen = rs.row_screen(prog, np.array([0.9, -0.1]), np.array([1.1, 0.1]))
    assert screen is not None and screen.always[2] and screen.always.sum() == 1
    pts, readings = np.array([[1.0, 0.0]]), _middles(prog, 1)
    assert not _full(prog, pts, readings)[0]
    assert not rs.screened_holds(screen, pts, readings)[0]


def _one_row(c0: float, r: float, target: tuple[float, float]) -> rs.RowScreen:
    """A screen of one row in one unknown whose model is the constant c0 +- r."""
    m = Models(np.array([c0]), np.zeros((1, 1)), np.zeros((1, 1)), np.array([r]))
    rows = Constraints(m, np.array([target[0]]), np.array([target[1]]), np.array([0]))
    ex = Expansion(np.zeros(1), np.ones(1), Pairs.of(1), rows)
    coef = np.zeros((2, 1))
    return rs.RowScreen(None, ex, -np.ones(1), np.ones(1),  # type: ignore[arg-type]
                        (np.array([target[0]]), np.array([target[1]])), np.array([0]),
                        np.zeros(2, dtype=bool), coef, rs.row_sizes(coef, 1))


def test_a_bound_at_the_targets_end_is_not_proven():
    # the float evaluation's roundings are charged: a value on the end proves nothing
    assert not rs._proven(_one_row(1.0, 0.0, (0.0, 1.0)), np.zeros((1, 1)))[0, 0]
    assert not rs._proven(_one_row(0.5, 0.5, (0.0, 1.0)), np.zeros((1, 1)))[0, 0]
    assert rs._proven(_one_row(0.5, 0.4999, (0.0, 1.0)), np.zeros((1, 1)))[0, 0]


def test_a_bound_just_beyond_the_targets_end_fails_no_point():
    # an excess within the evaluation's roundings refutes nothing; a larger one does
    one = np.zeros((1, 1))
    assert not rs._judged(_one_row(1.0 + 2.0**-50, 0.0, (0.0, 1.0)), one)[1][0, 0]
    assert rs._judged(_one_row(1.0 + 1e-9, 0.0, (0.0, 1.0)), one)[1][0, 0]
    assert rs._judged(_one_row(-0.5, 0.4, (0.0, 1.0)), one)[1][0, 0]
    assert not rs._judged(_one_row(-0.5, 0.5, (0.0, 1.0)), one)[1][0, 0]


def test_a_point_the_models_prove_false_is_not_evaluated(tmp_path):
    # a = 1.2, b = 0: every loop row's a + b is 0.2 from its y (0.01): refuted by the models
    prog = _line(tmp_path)
    screen = rs.row_screen(prog, np.array([0.9, -0.1]), np.array([1.3, 0.1]))
    assert screen is not None
    pts = np.array([[1.2, 0.0]])
    assert rs._needs(screen, pts)[1][0]
    with mock.patch.object(rs, "check_points", side_effect=AssertionError("evaluated")):
        assert not rs.screened_holds(screen, pts, _middles(prog, 1))[0]
    assert not _full(prog, pts, _middles(prog, 1))[0]


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), terms=st.integers(1, 40), rows=st.integers(1, 60),
       block=st.integers(-1, 80))
def test_the_blockwise_sizes_are_the_whole_arrays(seed, terms, rows, block):
    # any block (one row, more than the rows, none at all) gives the whole array's sums,
    # bit for bit, and each bounds the magnitudes' product with any terms in [-1, 1]
    rng = np.random.default_rng(seed)
    coef = rng.standard_normal((terms, rows)) * 10.0 ** rng.integers(-8, 8, (terms, rows))
    got = rs.row_sizes(coef, block)
    assert np.array_equal(got, rs.row_sizes(coef, rows + 1))
    assert np.array_equal(got, rs.row_sizes(coef, 1))
    t = rng.uniform(-1.0, 1.0, (5, terms))
    t[0] = 1.0
    assert np.all(np.abs(t) @ np.abs(coef) <= got)


def test_the_screen_keeps_the_models_coefficients_once(tmp_path):
    # the kept expansion's c1 and c2 are views of the screen's coef: not a second copy
    prog = _line(tmp_path)
    screen = rs.row_screen(prog, np.array([0.9, -0.05]), np.array([1.05, 0.05]))
    assert screen is not None
    m = screen.ex.rows.models
    assert np.shares_memory(m.c1, screen.coef) and np.shares_memory(m.c2, screen.coef)
    assert np.array_equal(np.hstack([m.c1, m.c2]).T, screen.coef)


def test_a_chunked_screen_reads_the_joined_coefficients_in_place(tmp_path):
    # expanded in chunks (by_terms): the screen's coef is the expansion's own buffer, and
    # it holds what the models of a whole expansion hold
    prog = _line(tmp_path, rows="1,1\n1,1.001\n0.5,0.5\n2,2\n1.5,1.5\n1,0.999\n")
    lo, hi = np.array([0.9, -0.05]), np.array([1.05, 0.05])
    whole = rs.row_screen(prog, lo, hi)
    rs.forget(prog, lo, hi)
    with mock.patch("calib_dsl.relax.taylor.CHUNK_SLOTS", 8), \
            mock.patch("calib_dsl.relax.taylor._terms_buffer", wraps=taylor._terms_buffer) as made:
        parts = rs.row_screen(prog, lo, hi)
    assert made.called  # (in chunks: the joined buffer made)
    assert whole is not None and parts is not None
    assert parts.ex.coef is parts.coef
    order = np.argsort(parts.ex.rows.slots, kind="stable")
    same = np.argsort(whole.ex.rows.slots, kind="stable")
    assert np.array_equal(parts.ex.rows.slots[order], whole.ex.rows.slots[same])
    assert np.array_equal(parts.coef[:, order], whole.coef[:, same])
    assert np.array_equal(parts.size[order], whole.size[same])
