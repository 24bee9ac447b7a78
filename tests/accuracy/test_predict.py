"""`calibc predict` and `validate`: boxes proven to hold the prediction for every parameter
vector consistent with the data; checked on simulated UR10 campaigns of known truth."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from calib_dsl.accuracy.certified import tightness
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
