"""The predicted configuration's readings moved within their errors for the inner ends
(accuracy/held_readings.py): on planar arms of random lengths, every moved reading lies
within its exact interval and moves the way its end's slope points; the ends are the
kinematics at the certified points and readings they name; the inner intervals contain
those at the readings' middles and are wider; the outer boxes are unchanged and hold the
held-out truths."""

from __future__ import annotations

import shutil

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib_dsl.accuracy.held_readings import reading_moves
from calib_dsl.analysis.certify_point import exact_inside, reading_slots
from calib_dsl.elaborate.elaborator import Inputs
from calib_dsl.pipeline import load, predict_at
from calib_dsl.settings import DEFAULT
from tests.accuracy.test_certified_predictions import (
    EXAMPLES,
    READING,
    assert_inner_ends,
    table,
    tip,
)


def _arm(tmp_path, l1, l2, seed, e=2e-6):
    rng = np.random.default_rng(seed)
    for name in ("planar_arm.cal", "planar_arm_robot.cal"):
        shutil.copy(EXAMPLES / name, tmp_path)
    q = rng.uniform(-np.pi, np.pi, (30, 2))
    x, y = tip(l1, l2, q[:, 0], q[:, 1])
    train = table(tmp_path / "train.csv", q, (x + rng.uniform(-e, e, 30),
                                              y + rng.uniform(-e, e, 30)))
    qh = rng.uniform(-np.pi, np.pi, (6, 2))
    truth = np.array(tip(l1, l2, qh[:, 0], qh[:, 1])).T
    held = table(tmp_path / "held.csv", qh, (truth[:, 0], truth[:, 1]))
    return Inputs(data={"m": train}, consts={"e": repr(e)}), held, qh, truth


@settings(max_examples=8, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.floats(0.85, 1.15), st.floats(0.35, 0.65), st.integers(0, 2 ** 31))
def test_moved_readings_widen_the_inner_ends_soundly(tmp_path, l1, l2, seed):
    inputs, held, qh, truth = _arm(tmp_path, l1, l2, seed)
    _, still = predict_at(tmp_path / "planar_arm.cal", held, inputs=inputs,
                          settings=DEFAULT.tuned(prediction_move_readings=False))
    _, p = predict_at(tmp_path / "planar_arm.cal", held, inputs=inputs)
    assert p is not None and still is not None
    assert np.all(p.lo <= truth) and np.all(truth <= p.hi)
    np.testing.assert_array_equal(p.lo, still.lo)
    np.testing.assert_array_equal(p.hi, still.hi)
    assert p.inner_lo is not None and p.inner_hi is not None
    assert still.inner_lo is not None and still.inner_hi is not None
    some = ~np.isnan(p.inner_lo)
    assert some.any() and np.array_equal(some, ~np.isnan(still.inner_lo))
    assert np.all(p.lo[some] <= p.inner_lo[some]) and np.all(p.inner_hi[some] <= p.hi[some])
    assert_inner_ends(p, qh, READING)
    # the middles' readings are one of the choices: the moved ends reach no less far, and
    # where the tip moves with the readings (it does, by about 1e-6), further
    assert np.all(p.inner_lo[some] <= still.inner_lo[some] + 1e-12)
    assert np.all(p.inner_hi[some] >= still.inner_hi[some] - 1e-12)
    grown = (p.inner_hi - p.inner_lo)[some] - (still.inner_hi - still.inner_lo)[some]
    assert np.median(grown) > READING


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2 ** 31))
def test_moves_stay_inside_the_readings_and_follow_the_slopes(seed):
    rng = np.random.default_rng(seed)
    prog = load(EXAMPLES / "planar_arm.cal")
    s = prog.slots
    assert s.measured_sides is not None and s.cell_row is not None and s.cell_col is not None
    targets = np.array(sorted(s.measured_sides), dtype=np.int64)
    rows = np.array([s.measured_sides[int(t)][0] for t in targets])
    ncol = int(s.cell_col.max()) + 1
    slope = rng.normal(size=(len(targets), ncol))
    slope[rng.uniform(size=slope.shape) < 0.2] = 0.0
    moves = reading_moves(prog, targets, slope, rows)
    assert moves is not None
    at = reading_slots(prog)
    rlo, rhi = exact_inside(s.lo[at], s.hi[at])
    assert np.all(moves.configs >= rlo) and np.all(moves.configs <= rhi)
    mid = 0.5 * s.lo[at] + 0.5 * s.hi[at]
    for i in range(len(targets)):
        mine = s.cell_row[at] == rows[i]
        for pick, side in ((0, 1.0), (1, -1.0)):
            step = moves.configs[moves.of[i, pick]][mine] - mid[mine]
            want = side * np.sign(slope[i, s.cell_col[at][mine]])
            assert np.all(np.sign(step) == want)
