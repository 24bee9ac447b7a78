"""Predictions as objectives over the calibration's second-order relaxation: on simulated
planar arms with a joint offset (the predictions curve in the parameters), the second-order
form is built (each row then takes the form that charges less at the box), the held-out true
positions lie in every box, and so do the
predictions (the kinematics written out by hand) of every parameter vector a dense sample
of the solve's box proves consistent with the data."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import calib_dsl.accuracy.predict as predict_module
from calib_dsl.accuracy.second_order import second_order
from calib_dsl.analysis.certify_point import check_points
from calib_dsl.elaborate.elaborator import Inputs
from calib_dsl.pipeline import load, predict_at, solve
from calib_dsl.relax.layout import independents

E = 0.02  # the measurements' error bound
MODEL = """param l1 in [0.8, 1.2];
param l2 in [0.3, 0.7];
param o in [-0.3, 0.3];
const e = 0.02;
table m = "m.csv" {
  q1, q2 : +- 1e-9;
  x, y : +- e;
}
for k in 1..rows(m) {
  l1 * cos(m.q1[k] + o) + l2 * cos(m.q1[k] + o + m.q2[k]) == m.x[k];
  l1 * sin(m.q1[k] + o) + l2 * sin(m.q1[k] + o + m.q2[k]) == m.y[k];
}
"""


def tip(l1, l2, o, q1, q2):
    return (l1 * np.cos(q1 + o) + l2 * np.cos(q1 + o + q2),
            l1 * np.sin(q1 + o) + l2 * np.sin(q1 + o + q2))


def table(path: Path, q: np.ndarray, xy: tuple[np.ndarray, np.ndarray] | None) -> Path:
    cols = (q[:, 0], q[:, 1], *xy) if xy is not None else (q[:, 0], q[:, 1])
    rows = [",".join(repr(float(v)) for v in r) for r in zip(*cols, strict=True)]
    path.write_text(("q1,q2,x,y\n" if xy is not None else "q1,q2\n") + "\n".join(rows) + "\n")
    return path


@pytest.fixture
def spy(monkeypatch):
    """The second_order results predict used (None: it fell back to the first order)."""
    seen = []

    def spied(*args, **kwargs):
        seen.append(second_order(*args, **kwargs))
        return seen[-1]

    monkeypatch.setattr(predict_module, "second_order", spied)
    return seen


@settings(max_examples=3, deadline=None,  # 8 in bench/checks/test_soundness_full.py
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.floats(0.85, 1.15), st.floats(0.35, 0.65), st.floats(-0.2, 0.2),
       st.integers(0, 2 ** 31))
def test_every_consistent_vectors_prediction_lies_in_its_box(tmp_path, spy, l1, l2, o, seed):
    rng = np.random.default_rng(seed)
    (tmp_path / "arm.cal").write_text(MODEL)
    q = rng.uniform(-np.pi, np.pi, (8, 2))
    x, y = tip(l1, l2, o, q[:, 0], q[:, 1])
    train = table(tmp_path / "m.csv", q, (x + rng.uniform(-E, E, len(x)),
                                          y + rng.uniform(-E, E, len(y))))
    qh = rng.uniform(-np.pi, np.pi, (6, 2))
    held = table(tmp_path / "held.csv", qh, None)
    inputs = Inputs(data={"m": train})
    spy.clear()
    _, p = predict_at(tmp_path / "arm.cal", held, inputs=inputs)
    assert p is not None and spy and spy[-1] is not None  # the second-order form was built
    truth = np.array(tip(l1, l2, o, qh[:, 0], qh[:, 1])).T
    assert np.all(p.lo <= truth) and np.all(truth <= p.hi)
    # a dense sample of the solve's box: the vectors proven consistent predict inside
    prog = load(tmp_path / "arm.cal", inputs=inputs)
    sol = solve(prog)
    ind = independents(prog)
    points = rng.uniform(sol.lo[ind], sol.hi[ind], (4000, len(ind)))
    good = points[[c.holds for c in check_points(prog, points)]]
    assert len(good)  # (else the sample proves nothing)
    names = [prog.slots.names[k] for k in ind]
    at = np.array([tip(*(w[names.index(n)] for n in ("l1", "l2", "o")), qh[:, 0], qh[:, 1])
                   for w in good])  # (points, 2, rows)
    for j in range(2):
        assert np.all(p.lo[:, j] <= at[:, j, :].min(axis=0, initial=np.inf))
        assert np.all(at[:, j, :].max(axis=0, initial=-np.inf) <= p.hi[:, j])
    # the inner interval is the hull of certified predictions, inside the box
    some = ~np.isnan(p.inner_lo)
    assert np.all(p.lo[some] <= p.inner_lo[some]) and np.all(p.inner_hi[some] <= p.hi[some])


def _arm(tmp_path: Path, seed: int) -> tuple[Inputs, Path, np.ndarray]:
    rng = np.random.default_rng(seed)
    (tmp_path / "arm.cal").write_text(MODEL)
    q = rng.uniform(-np.pi, np.pi, (8, 2))
    x, y = tip(1.0, 0.5, 0.1, q[:, 0], q[:, 1])
    train = table(tmp_path / "m.csv", q, (x + rng.uniform(-E, E, len(x)),
                                          y + rng.uniform(-E, E, len(y))))
    qh = rng.uniform(-np.pi, np.pi, (20, 2))
    return Inputs(data={"m": train}), table(tmp_path / "held.csv", qh, None), qh


@pytest.mark.parametrize("seed", [3, 17])
def test_the_first_order_form_holds_the_truth_and_the_second_is_tighter(tmp_path, monkeypatch,
                                                                        seed):
    inputs, held, qh = _arm(tmp_path, seed)
    truth = np.array(tip(1.0, 0.5, 0.1, qh[:, 0], qh[:, 1])).T
    _, fine = predict_at(tmp_path / "arm.cal", held, inputs=inputs)
    monkeypatch.setattr(predict_module, "second_order", lambda *a, **k: None)
    _, first = predict_at(tmp_path / "arm.cal", held, inputs=inputs)
    assert fine is not None and first is not None
    for p in (fine, first):
        assert np.all(p.lo <= truth) and np.all(truth <= p.hi)
    assert np.median(fine.hi - fine.lo) < np.median(first.hi - first.lo)


@pytest.mark.parametrize("seed", [3, 17])
def test_a_row_whose_lp_stopped_falls_back_to_the_first_order_lp(tmp_path, monkeypatch, spy,
                                                                  seed):
    """The second-order LPs stopped after one pivot: their rows are not settled and take
    the first-order LP's bound too, so no box is wider than the first-order form's."""
    import calib_dsl.accuracy.second_order as second_module

    inputs, held, qh = _arm(tmp_path, seed)
    truth = np.array(tip(1.0, 0.5, 0.1, qh[:, 0], qh[:, 1])).T
    with monkeypatch.context() as m:
        m.setattr(predict_module, "second_order", lambda *a, **k: None)
        _, first = predict_at(tmp_path / "arm.cal", held, inputs=inputs)
    real = second_module.batch_bounds

    def stopped(rel, objectives, settings, directions=None):
        lp = replace(settings.lp, iterations=1)
        return real(rel, objectives, replace(settings, lp=lp, prediction_lp_runs=1),
                    directions)

    monkeypatch.setattr(second_module, "batch_bounds", stopped)
    spy.clear()
    _, p = predict_at(tmp_path / "arm.cal", held, inputs=inputs)
    assert p is not None and first is not None
    found = spy[-1]
    assert found is not None and found.settled is not None and not found.settled.all()
    assert np.all(p.lo <= truth) and np.all(truth <= p.hi)
    # (the same LP's certified bound in both runs, up to HiGHS's tolerance)
    slack = 1e-9 * (1 + np.abs(first.lo) + np.abs(first.hi))
    assert np.all(p.hi - p.lo <= first.hi - first.lo + slack)
