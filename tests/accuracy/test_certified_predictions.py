"""Predictions with a certificate: on simulated planar arms of random true lengths, the
held-out true positions lie in every predicted box, the certified inner intervals lie in the
boxes, each end is the prediction (the kinematics written out by hand) of the certified
point it names, and each of those points is proven consistent with the data."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib_dsl.accuracy.certified import tightness
from calib_dsl.analysis.certify_point import check_point
from calib_dsl.analysis.existence import prove_point
from calib_dsl.elaborate.elaborator import Inputs
from calib_dsl.pipeline import load, predict_at
from calib_dsl.relax.layout import independents

EXAMPLES = Path(__file__).resolve().parents[2] / "models" / "examples"
E = 0.02  # the measurements' error bound of the test's model
READING = 1e-6  # planar_arm.cal's joint readings' error bound


def tip(l1, l2, q1, q2):
    return (l1 * np.cos(q1) + l2 * np.cos(q1 + q2), l1 * np.sin(q1) + l2 * np.sin(q1 + q2))


def assert_inner_ends(p, qh: np.ndarray, tol: float) -> None:
    """Each inner end of the planar arm's prediction `p` (held readings `qh`, +- `tol`):
    the hand-written kinematics at the certified point and the readings it names, within
    rounding; those readings within `tol` of the file's; every end between the predictions
    at all the certified points with the readings anywhere within `tol` (by a bound on the
    kinematics' slope in the readings: at most the arm's reach, 2, times the move)."""
    some = ~np.isnan(p.inner_lo)
    rows, cols = np.nonzero(some)
    assert p.held_columns == ("q1", "q2") and p.inner_held is not None
    moved = p.inner_held[rows, cols] - qh[rows][:, None, :]  # (cells, 2 ends, 2 readings)
    assert np.all(np.abs(moved) <= tol)
    k1, k2 = p.names.index("l1"), p.names.index("l2")
    for end, got in ((0, p.inner_lo), (1, p.inner_hi)):
        w = p.inner_points[p.inner_from[rows, cols, end]]
        q = p.inner_held[rows, cols, end]
        x, y = tip(w[:, k1], w[:, k2], q[:, 0], q[:, 1])
        np.testing.assert_allclose(got[some], np.where(cols == 0, x, y), rtol=0, atol=1e-12)
    at = np.array([tip(w[k1], w[k2], qh[:, 0], qh[:, 1]) for w in p.inner_points])
    at = at.transpose(0, 2, 1)  # (points, rows, columns)
    reach = 2 * 2 * tol + 1e-12  # (two readings, each moving the tip by at most 2 tol)
    assert np.all(at.min(axis=0)[some] - reach <= p.inner_lo[some])
    assert np.all(p.inner_hi[some] <= at.max(axis=0)[some] + reach)


def table(path: Path, q: np.ndarray, xy: tuple[np.ndarray, np.ndarray]) -> Path:
    rows = [",".join(repr(float(v)) for v in (a, b, x, y))
            for (a, b), x, y in zip(q, *xy, strict=True)]
    path.write_text("q1,q2,x,y\n" + "\n".join(rows) + "\n")
    return path


@settings(max_examples=12, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.floats(0.85, 1.15), st.floats(0.35, 0.65), st.integers(0, 2 ** 31))
def test_true_positions_lie_in_the_boxes_and_inner_ends_are_certified(tmp_path, l1, l2, seed):
    rng = np.random.default_rng(seed)
    for name in ("planar_arm.cal", "planar_arm_robot.cal"):
        shutil.copy(EXAMPLES / name, tmp_path)
    q = rng.uniform(-np.pi, np.pi, (10, 2))
    x, y = tip(l1, l2, q[:, 0], q[:, 1])
    noisy = (x + rng.uniform(-E, E, len(x)), y + rng.uniform(-E, E, len(y)))
    train = table(tmp_path / "train.csv", q, noisy)
    qh = rng.uniform(-np.pi, np.pi, (6, 2))
    truth = np.array(tip(l1, l2, qh[:, 0], qh[:, 1])).T
    held = table(tmp_path / "held.csv", qh, (truth[:, 0], truth[:, 1]))
    inputs = Inputs(data={"m": train}, consts={"e": repr(E)})
    _, p = predict_at(tmp_path / "planar_arm.cal", held, inputs=inputs)
    assert p is not None and p.columns == ["x", "y"]
    assert np.all(p.lo <= truth) and np.all(truth <= p.hi)
    assert p.inner_lo is not None and p.inner_hi is not None and p.inner_points is not None
    some = ~np.isnan(p.inner_lo)
    assert some.any()
    assert np.all(p.lo[some] <= p.inner_lo[some]) and np.all(p.inner_hi[some] <= p.hi[some])
    assert p.inner_from is not None and np.all((p.inner_from >= 0) == some[..., None])
    assert_inner_ends(p, qh, READING)
    prog = load(tmp_path / "planar_arm.cal", inputs=inputs)
    order = [p.names.index(prog.slots.names[k]) for k in independents(prog)]
    assert p.inner_readings is not None
    for w, r in zip(p.inner_points, p.inner_readings, strict=True):
        check = check_point(prog, w[order], r)
        assert check.holds or prove_point(prog, w[order], r, check)
    t = tightness(p.lo, p.hi, p.inner_lo, p.inner_hi)
    assert t["median_ratio"] is None or t["median_ratio"] >= 1.0
