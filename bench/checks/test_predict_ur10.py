"""`calibc predict` and `validate` on simulated UR10 campaigns (subprocess solves of 40 rows,
predictions of 20): too heavy for `make test`, where tests/accuracy/test_predict.py keeps a
linear model's predictions holding the truth and tests/accuracy/test_certified_predictions.py
the true positions inside their certified boxes."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

from calib_dsl.elaborate.elaborator import Inputs
from calib_dsl.pipeline import predict_at
from tests.accuracy.test_predict import NOISE, TRACKER, simulated


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
