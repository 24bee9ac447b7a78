"""Corrected linearized extremes (accuracy/corrections.py) on a curved solution set: a point
(a, b) known by its distance from one far anchor, within +-E, is a thin arc, which the model
linearized at its centre (a straight strip) misses at its ends. The corrections raise the
ends the pull-back alone leaves short; every point they return is proven; and predictions
(distances from other anchors) keep the truth and consistent vectors in their boxes, their
inner ends the distances at the certified points they name."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib_dsl.accuracy.extremes import certified_extremes
from calib_dsl.analysis.certify_point import check_point
from calib_dsl.elaborate.elaborator import Inputs
from calib_dsl.inner.bounds import inner_bounds
from calib_dsl.pipeline import load, predict_at, solve
from calib_dsl.relax.layout import independents
from calib_dsl.settings import Settings

E = 0.05
MODEL = f"""
param a in [-1, 1];
param b in [-0.5, 0.5];
table m = "train.csv" {{
  x, y : +- 1e-9;
  d : +- {E};
}}
for k in 1..rows(m) {{
  sqrt(sqr(a - m.x[k]) + sqr(b - m.y[k])) == m.d[k];
}}
"""


def table(path: Path, anchors: np.ndarray, d: np.ndarray) -> Path:
    path.write_text("x,y,d\n" + "".join(f"{float(x)!r},{float(y)!r},{float(v)!r}\n"
                                        for (x, y), v in zip(anchors, d, strict=True)))
    return path


def arc(tmp: Path, radius: float, measured: float) -> Path:
    """The model, calibrated on one anchor `radius` below the origin at distance
    `measured`: an arc of sag about 1 / (2 radius) over a in [-1, 1], 2 E thick."""
    (tmp / "arc.cal").write_text(MODEL)
    table(tmp / "train.csv", np.array([[0.0, -radius]]), np.array([measured]))
    return tmp / "arc.cal"


def solved_arc(tmp_path):
    """The arc's program solved: (program, solution, independents, settings, the inner
    bounds' centre, the box over the independents)."""
    prog = load(arc(tmp_path, 20.0, 20.0))
    sol = solve(prog)
    ind = independents(prog)
    s = Settings()
    centre = inner_bounds(prog, sol.lo, sol.hi, sol.starts, s).centre
    assert centre is not None
    box = (sol.lo[ind], sol.hi[ind])
    return prog, sol, ind, s, centre, box


def test_corrections_raise_ends_the_centres_linearization_leaves_short(tmp_path):
    prog, sol, ind, s, centre, box = solved_arc(tmp_path)
    directions = np.array([[1.0, 0.2], [0.3, 1.0], [-1.0, 0.5]])
    best = {}
    for corrections in (0, s.prediction_corrections):
        found = certified_extremes(prog, box, centre, directions, np.zeros((0, 2)),
                                   s.tuned(prediction_corrections=corrections))
        assert found
        for p, r in found:
            assert check_point(prog, p, r).holds
        best[corrections] = (np.array([p for p, _ in found]) @ directions.T).max(axis=0)
    # the pull-back stops where the segment to the centre leaves the arc; the corrected
    # optimum slides along it to the end of a
    gained = best[s.prediction_corrections] - best[0]
    assert np.all(gained >= -1e-9) and gained.max() > 5e-3


def distances(points: np.ndarray, anchors: np.ndarray) -> np.ndarray:
    """(points, anchors): the model's prediction, written out by hand."""
    return np.hypot(points[:, None, 0] - anchors[None, :, 0],
                    points[:, None, 1] - anchors[None, :, 1])


@settings(max_examples=3, deadline=None,  # 8 in bench/checks/test_soundness_full.py
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.floats(8.0, 30.0), st.floats(-0.6, 0.6), st.floats(-1.0, 1.0),
       st.integers(0, 2**31))
def test_predictions_on_an_arc_keep_the_truth_and_name_certified_points(
        tmp_path, radius, a, noise, seed):
    rng = np.random.default_rng(seed)
    truth = np.array([a, -radius + np.sqrt(radius**2 - a**2)])  # on the arc's middle
    model = arc(tmp_path, radius, radius + 0.5 * E * noise)
    angles = rng.uniform(0, 2 * np.pi, 5)
    anchors = 10.0 * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    held = table(tmp_path / "held.csv", anchors, distances(truth[None], anchors)[0])
    _, p = predict_at(model, held, inputs=Inputs(data={"m": tmp_path / "train.csv"}))
    assert p is not None and p.columns == ["d"]
    assert np.all(p.lo[:, 0] <= p.measured[:, 0]) and np.all(p.measured[:, 0] <= p.hi[:, 0])
    # vectors drawn in the solve's box and proven consistent lie in every box
    prog = load(model)
    ind = independents(prog)
    names = [prog.slots.names[k] for k in ind]
    drawn = rng.uniform(0, 1, (200, 2)) * 2 - 1
    drawn[:, 1] = -radius + np.sqrt(radius**2 - drawn[:, 0]**2) + rng.uniform(-E, E, 200)
    proven = [v for v in drawn if check_point(prog, v).holds]
    assert proven
    at = distances(np.array(proven), anchors)
    assert np.all(p.lo[:, 0] <= at.min(axis=0)) and np.all(at.max(axis=0) <= p.hi[:, 0])
    # each inner end: the distance at the certified point it names, each point proven
    assert p.inner_from is not None and p.inner_points is not None
    assert p.inner_lo is not None and p.inner_hi is not None and p.inner_readings is not None
    some = ~np.isnan(p.inner_lo[:, 0])
    assert some.any()
    order = [p.names.index(n) for n in names]
    points = p.inner_points[:, order]
    rows = np.flatnonzero(some)
    # (at the anchor's readings it names, within their +- 1e-9 of the file's)
    assert p.held_columns == ("x", "y") and p.inner_held is not None
    assert np.all(np.abs(p.inner_held[rows, 0] - anchors[rows][:, None]) <= 1e-9)
    for end, got in ((0, p.inner_lo), (1, p.inner_hi)):
        named = points[p.inner_from[rows, 0, end]]
        moved = p.inner_held[rows, 0, end]
        pred = np.hypot(named[:, 0] - moved[:, 0], named[:, 1] - moved[:, 1])
        np.testing.assert_allclose(got[rows, 0], pred, rtol=0, atol=1e-12)
    assert np.all(p.lo[some, 0] <= p.inner_lo[some, 0])
    assert np.all(p.inner_hi[some, 0] <= p.hi[some, 0])
    for w, r in zip(points, p.inner_readings, strict=True):
        assert check_point(prog, w, r).holds


def test_each_signs_thread_finds_the_points_of_both_signs_together(tmp_path):
    """The candidates of each sign found and corrected on a thread of their own, the far
    optima pulled back beside them: as many points, each proven, reaching as far along
    every direction as both signs corrected together on one HiGHS model (the LPs' bases
    differ only by the models' histories: their optima agree to the LPs' tolerances)."""
    prog, sol, ind, s, centre, box = solved_arc(tmp_path)
    directions = np.array([[1.0, 0.2], [0.3, 1.0], [-1.0, 0.5], [0.7, -0.6]])
    far = np.array([[0.9, 0.1], [-0.8, 0.05]])
    reach = {}
    for workers in (1, 2):
        found = certified_extremes(prog, box, centre, directions, far,
                                   s.tuned(lp=replace(s.lp, workers=workers)))
        for p, r in found:
            assert check_point(prog, p, r).holds
        reach[workers] = (len(found), np.array([p for p, _ in found]) @ directions.T)
    assert reach[1][0] == reach[2][0]
    np.testing.assert_allclose(reach[2][1].max(axis=0), reach[1][1].max(axis=0), atol=1e-6)
    np.testing.assert_allclose(reach[2][1].min(axis=0), reach[1][1].min(axis=0), atol=1e-6)


def test_the_relaxations_optima_are_pulled_back_only_without_linearized_candidates(tmp_path):
    """With the linearized model's candidates, the relaxation's optima are not pulled back:
    the same points with them or without (either worker count), and those points reach at
    least as far along every direction as the optima pulled back alone (which is what
    the search falls back to where there is no linearized candidate: no direction)."""
    prog, sol, ind, s, centre, box = solved_arc(tmp_path)
    directions = np.array([[1.0, 0.2], [0.3, 1.0], [-1.0, 0.5], [0.7, -0.6]])
    far = np.array([[0.9, 0.1], [-0.8, 0.05]])
    reach = []
    for workers in (1, 2):
        t = s.tuned(lp=replace(s.lp, workers=workers))
        with_far = certified_extremes(prog, box, centre, directions, far, t)
        without = certified_extremes(prog, box, centre, directions, np.zeros((0, 2)), t)
        assert len(with_far) == len(without) > 0
        for (p, r), (q, u) in zip(with_far, without, strict=True):
            assert np.array_equal(p, q) and np.array_equal(r, u)
        reach.append(np.array([p for p, _ in with_far]) @ directions.T)
    alone = certified_extremes(prog, box, centre, np.zeros((0, 2)), far, s)
    assert len(alone) == len(far)
    for p, r in alone:
        assert check_point(prog, p, r).holds
    pulled = np.array([p for p, _ in alone]) @ directions.T
    for got in reach:
        assert np.all(got.max(axis=0) >= pulled.max(axis=0) - 1e-9)
        assert np.all(got.min(axis=0) <= pulled.min(axis=0) + 1e-9)
