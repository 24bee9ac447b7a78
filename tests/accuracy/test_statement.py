"""The accuracy statement of a solve: residuals at the nominal, least-squares and certified
points, and the guaranteed bound over the data's own poses. Checked against the planar arm's
forward kinematics written out by hand, and on the simulated UR10 campaign (its true values
known): calibration does not worsen the statistics, and the bound holds every consistent
vector's residuals."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from planar_arm import simulated_arm, tip

from calib_dsl.accuracy.points import certified_centre
from calib_dsl.accuracy.statement import (
    accuracy,
    distances,
    independent_point,
    layout,
    nominal_point,
    point_residuals,
    statistics,
)
from calib_dsl.analysis.residuals import residual_ranges
from calib_dsl.pipeline import SolveRequest, solve_report
from calib_dsl.relax.layout import independents
from calib_dsl.report.accuracy import accuracy_json, render_accuracy
from calib_dsl.report.strict_json import dumps, strict_loads

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    """The planar arm solved on 12 simulated noisy rows: its report and the rows read."""
    tmp = tmp_path_factory.mktemp("arm")
    rows = simulated_arm(tmp, 12, 3)
    return solve_report(SolveRequest(tmp / "planar_arm.cal")), rows


@pytest.fixture(scope="module")
def ur10():
    return solve_report(SolveRequest(ROOT / "models" / "ur10_simulated.cal"))


def test_residuals_are_the_hand_written_kinematics(arm):
    run, rows = arm
    acc = run.extra.accuracy
    assert acc.at.columns == ["x", "y"] and len(acc.at.configurations) == len(rows)
    names = [run.prog.slots.names[k] for k in independents(run.prog)]
    for label, r in acc.points.items():
        p = acc_point(run, label)
        l1, l2 = p[names.index("l1")], p[names.index("l2")]
        for i, (_, k) in enumerate(acc.at.configurations):
            row = rows[k - 1]
            x, y = tip(l1, l2, row["q1"], row["q2"])
            np.testing.assert_allclose(r[i], [row["x"] - x, row["y"] - y], atol=1e-12)


def acc_point(run, label: str) -> np.ndarray:
    if label == "nominal":  # [0.8, 1.2] and [0.3, 0.7]: no `c +- w`, the domains' middles
        return np.array([1.0, 0.5])
    if label == "certified":
        return certified_centre(run.extra.inner)
    return lsq_of(run)


def lsq_of(run) -> np.ndarray:
    from calib_dsl.analysis.lsq import estimate
    ind = independents(run.prog)
    mid = 0.5 * (run.res.lo[ind] + run.res.hi[ind])
    return estimate(run.prog, start=mid).values


@pytest.mark.slow
def test_statistics_are_numpy_s(ur10):
    acc = ur10.extra.accuracy
    found = strict_loads(dumps(accuracy_json(acc, "mm")))
    assert found["unit"] == "mm" and found["columns"] == ["x", "y", "z"]
    for label, point in found["points"].items():
        r = acc.points[label]
        d = np.sqrt(np.sum(r ** 2, axis=1))
        np.testing.assert_allclose(point["distances"], d, rtol=1e-12)
        assert point["distance"]["rms"] == pytest.approx(np.sqrt(np.mean(d ** 2)))
        assert point["distance"]["max"] == pytest.approx(d.max())
        assert point["distance"]["p95"] == pytest.approx(np.percentile(d, 95))
        assert point["distance"]["mean"] == pytest.approx(d.mean())
        for j, c in enumerate(found["columns"]):
            assert point["axes"][c]["mean"] == pytest.approx(np.mean(r[:, j]))
            assert point["axes"][c]["max"] == pytest.approx(np.max(np.abs(r[:, j])))
    assert found["bound"]["max"] == pytest.approx(np.max(acc.bound))
    assert found["bound"]["median"] == pytest.approx(np.median(acc.bound))
    text = "\n".join(render_accuracy(found))
    assert "in mm" in text and "guaranteed" in text


@pytest.mark.slow
def test_calibration_does_not_worsen_the_statistics(ur10):
    acc = ur10.extra.accuracy
    assert {"nominal", "least_squares", "certified"} == set(acc.points)
    before = statistics(distances(acc.points["nominal"]))
    for label in ("least_squares", "certified"):
        after = statistics(distances(acc.points[label]))
        for k in ("mean", "rms", "p95", "max"):
            assert after[k] <= before[k], (label, k)


@pytest.mark.slow
def test_the_bound_holds_every_consistent_vector(ur10):
    """At the true values (the simulation's), the least-squares point and every certified
    point of the inner bounds (each proven consistent): every residual is within the bound."""
    acc, prog = ur10.extra.accuracy, ur10.prog
    assert np.all(np.isfinite(acc.bound))
    true = independent_point(prog, prog.true_values)
    assert true is not None
    at = layout(prog)
    for p in [true, *(w.point for w in ur10.extra.inner.witnesses)]:
        r = point_residuals(prog, at, p)
        assert np.all(np.abs(r) <= acc.worst)
        assert np.all(distances(r) <= acc.bound)
    # the least-squares point need not be consistent (it minimizes the squares, not the
    # largest residual): the bound over the whole box holds it, as it holds every point above
    ind = independents(prog)
    lsq = lsq_of(ur10)
    assert np.all((ur10.res.lo[ind] <= lsq) & (lsq <= ur10.res.hi[ind]))
    for p in [true, lsq, *(w.point for w in ur10.extra.inner.witnesses)]:
        r = point_residuals(prog, at, p)
        assert np.all(np.abs(r) <= acc.box_worst)
        assert np.all(distances(r) <= acc.box_bound)
    assert np.all(acc.bound <= acc.box_bound)
    # and it says something: within a few error bounds e = 0.1 mm per axis
    assert np.max(acc.bound) < 3 * np.sqrt(3) * 0.1


def test_a_model_without_measured_columns_says_why(tmp_path):
    model = tmp_path / "free.cal"
    model.write_text("var x in [0, 1];\nvar y in [0, 1];\nvar z in [1, 4];\nz == x + y;\n")
    run = solve_report(SolveRequest(model))
    assert run.extra.accuracy is None and "accuracy" not in run.as_json()
    assert "accuracy: the model compares no computed value" in run.text()


@settings(max_examples=200, deadline=None)
@given(st.floats(0, 1), st.floats(0, 1))
def test_the_box_bound_holds_every_vector_of_the_box(arm, a, b):
    """Any (l1, l2) of the result box, the hand-written kinematics at the readings: within
    the box's bound on every axis and in distance."""
    run, rows = arm
    acc, prog = run.extra.accuracy, run.prog
    ind = independents(prog)
    names = [prog.slots.names[k] for k in ind]
    lo, hi = run.res.lo[ind], run.res.hi[ind]
    p = lo + np.array([a, b]) * (hi - lo)
    l1, l2 = p[names.index("l1")], p[names.index("l2")]
    for i, (_, k) in enumerate(acc.at.configurations):
        row = rows[k - 1]
        x, y = tip(l1, l2, row["q1"], row["q2"])
        r = np.array([row["x"] - x, row["y"] - y])
        assert np.all(np.abs(r) <= acc.box_worst[i])
        assert np.hypot(*r) <= acc.box_bound[i]


@pytest.mark.slow
def test_columns_read_in_an_angle_unit_stay_out_of_the_distance(ur10):
    prog, res = ur10.prog, ur10.res
    ind = independents(prog)
    box = {prog.slots.names[k]: (float(res.lo[k]), float(res.hi[k])) for k in ind}
    p = {"nominal": nominal_point(prog)}
    acc = accuracy(prog, residual_ranges(prog, box), p, angles=frozenset({"z"}))
    r = acc.points["nominal"]
    np.testing.assert_allclose(distances(r, acc.among), np.hypot(r[:, 0], r[:, 1]))
    found = accuracy_json(acc, "mm")
    assert found["distance_columns"] == ["x", "y"] and set(found["points"]["nominal"]["axes"]) \
        == {"x", "y", "z"}
    assert np.all(acc.bound <= ur10.extra.accuracy.bound)  # one axis fewer


@pytest.mark.slow
def test_the_statement_is_each_part_computed_afresh(ur10):
    """The statement reuses the polish's evaluations at the least-squares point and the
    load's fit: every array equals the one computed on its own, bit for bit."""
    acc, prog, res = ur10.extra.accuracy, ur10.prog, ur10.res
    at, ind = layout(prog), independents(prog)
    from calib_dsl.accuracy.fit import polish
    from calib_dsl.settings import DEFAULT

    assert {"nominal", "least_squares", "certified"} == set(acc.points)
    centre = certified_centre(ur10.extra.inner)
    assert centre is not None
    for label, p in (("nominal", nominal_point(prog)),
                     ("least_squares", polish(prog, ur10.problem.fit.values, DEFAULT).values),
                     ("certified", centre)):
        assert np.array_equal(acc.points[label], point_residuals(prog, at, p), equal_nan=True)
    box = {prog.slots.names[k]: (float(res.lo[k]), float(res.hi[k])) for k in ind}
    fresh = accuracy(prog, residual_ranges(prog, box), {})
    for field in ("worst", "bound", "box_worst", "box_bound"):
        assert np.array_equal(getattr(acc, field), getattr(fresh, field), equal_nan=True)


@pytest.mark.slow
def test_the_statement_from_the_loads_fit_is_one_from_a_fresh_fit(ur10):
    """The least-squares point polished from the load's fit (its rows given, not evaluated
    again) has the sum of squares of one polished afresh from the certified centre, within
    the fit's tolerance, and residuals within its square root of their size."""
    from calib_dsl.accuracy.points import solve_statement
    from calib_dsl.settings import DEFAULT

    prog, res, extra = ur10.prog, ur10.res, ur10.extra
    assert ur10.problem.fit is not None and ur10.problem.fit.rows is not None
    mine = extra.accuracy
    fresh = solve_statement(prog, res.lo, res.hi, None, extra.inner, frozenset(), DEFAULT)
    a, b = mine.points["least_squares"], fresh.points["least_squares"]
    assert np.sum(a ** 2) == pytest.approx(np.sum(b ** 2), rel=DEFAULT.fit_tolerance)
    assert np.allclose(a, b, rtol=0, atol=np.sqrt(DEFAULT.fit_tolerance) * np.max(np.abs(b)))
    for label in ("nominal", "certified"):
        assert np.array_equal(mine.points[label], fresh.points[label], equal_nan=True)
