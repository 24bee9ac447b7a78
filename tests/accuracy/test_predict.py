"""`calibc predict` and `validate`: boxes proven to hold the prediction for every parameter
vector consistent with the data; checked on simulated UR10 campaigns of known truth."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calib_dsl.accuracy.certified import tightness
from calib_dsl.elaborate.elaborator import Inputs
from calib_dsl.pipeline import predict_at

ROOT = Path(__file__).resolve().parents[2]
TRACKER = ROOT / "models" / "ur10_tracker.cal"
SIMULATED = ROOT / "models" / "ur10_simulated.cal"
NOISE = 0.1  # mm: ur10_simulated.cal's noise on each measured coordinate


def simulated(calibc, path: Path, rows: int, seed: int) -> Path:
    out = subprocess.run([*calibc, "simulate", str(SIMULATED), "--configs", str(rows), "--seed",
                          str(seed), "-o", str(path)], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    return path


@pytest.mark.slow
@pytest.mark.parametrize("seed", [3, 4])
def test_held_out_measurements_lie_in_their_boxes(tmp_path, calibc, seed):
    """Calibrated on 40 rows, each held-out measurement (truth + noise within NOISE) lies
    within NOISE of its box: the truth's prediction is inside."""
    train = simulated(calibc, tmp_path / "train.csv", 40, seed)
    held = simulated(calibc, tmp_path / "held.csv", 20, seed + 100)
    sol, p = predict_at(TRACKER, held, inputs=Inputs(data={"m": train}, consts={"e": "0.5"}))
    assert p is not None and p.columns == ["x", "y", "z"] and len(p.rows) == 20
    assert np.all(p.measured >= p.lo - NOISE) and np.all(p.measured <= p.hi + NOISE)
    assert np.all(p.covered())
    assert np.all(p.hi - p.lo < 30)  # narrower than the priors' sum (a real prediction)


@pytest.mark.slow
def test_predict_needs_no_measurements_and_validate_reports(tmp_path, calibc):
    held = simulated(calibc, tmp_path / "held.csv", 6, 9)
    lines = held.read_text().splitlines()
    header = lines[0].split(";")
    keep = [i for i, h in enumerate(header) if not h.startswith("measurement_")]
    joints = tmp_path / "joints.csv"
    joints.write_text("\n".join(";".join(ln.split(";")[i] for i in keep) for ln in lines) + "\n")
    out = subprocess.run([*calibc, "predict", str(TRACKER), "--at", str(joints), "--json", "-",
                          "--csv", str(tmp_path / "p.csv")], capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert data["columns"] == ["x", "y", "z"] and len(data["rows"]) == 6
    assert (tmp_path / "p.csv").read_text().startswith("row,line,x_lo,x_hi")
    val = subprocess.run([*calibc, "validate", str(TRACKER), "--at", str(held), "--at-skip",
                          "1..6:2", "--json", "-"], capture_output=True, text=True, timeout=600)
    assert val.returncode == 0, val.stderr
    v = json.loads(val.stdout)
    assert v["rows"] == 3 and v["coverage"] == 1.0
    assert 0 < v["width"]["median"] <= v["width"]["max"]
    for doc in (data, v):
        assert 1.0 <= doc["tightness"]["median_ratio"] <= doc["tightness"]["worst_ratio"]
    for row in data["rows"]:
        for c in data["columns"]:
            a, b = row["inner"][c]
            assert row[c][0] <= a <= b <= row[c][1]
    for row in v["held_out"]:
        for c in row["columns"].values():
            assert c["predicted"][0] <= c["inner"][0] <= c["inner"][1] <= c["predicted"][1]
    for row in data["rows"][1::2]:  # the same configurations predict the same boxes
        assert row["x"][0] < row["x"][1]


LINE = """param a in [-10, 10]; param b in [-10, 10];
table m = "d.csv" { x : +- 1e-9; y : +- 0.2; }
for k in 1..rows(m) { a * m.x[k] + b == m.y[k]; }
"""


@settings(max_examples=30, deadline=None)
@given(st.floats(-3, 3), st.floats(-3, 3), st.integers(0, 10**6))
def test_a_linear_model_predicts_the_truth_inside(tmp_path_factory, a, b, seed):
    """Data drawn from a true line with noise within the bound; at new abscissae (the file
    without its y column) the truth's value lies in every predicted box."""
    from hypothesis import assume

    assume(abs(a) > 1e-3)
    rng = np.random.default_rng(seed)
    tmp = tmp_path_factory.mktemp("line")
    x = rng.uniform(-2, 2, 8)
    y = a * x + b + rng.uniform(-0.19, 0.19, 8)
    (tmp / "d.csv").write_text("x,y\n" + "\n".join(f"{u!r},{v!r}" for u, v in
                                                     zip(x.tolist(), y.tolist(), strict=True)))
    new = rng.uniform(-4, 4, 5)
    (tmp / "at.csv").write_text("x\n" + "\n".join(repr(u) for u in new.tolist()) + "\n")
    (tmp / "line.cal").write_text(LINE)
    sol, p = predict_at(tmp / "line.cal", tmp / "at.csv")
    assert p is not None and p.columns == ["y"]
    truth = a * new + b
    assert np.all(p.lo[:, 0] <= truth) and np.all(truth <= p.hi[:, 0])
    # a polytope: the LPs are exact and their optima certified points, so the boxes are
    # what the data allow (outer over inner at most the bisection's last step)
    t = tightness(p.lo, p.hi, p.inner_lo, p.inner_hi)
    assert t["worst_ratio"] is not None and 1.0 <= t["worst_ratio"] <= 1.05
