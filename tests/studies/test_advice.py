"""`calibc identify`: a rank judged against the data's error bounds, parameters named by what
absorbs them, a well-conditioned subset; on the UR10 with all 33 parameters free."""

from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

from calib_dsl.pipeline import load
from calib_dsl.settings import Settings
from calib_dsl.studies.advice import advise, render

SEEN, COND_MAX = Settings().seen, Settings().subset_cond

ROOT = Path(__file__).resolve().parents[2]
ALL = ROOT / "models" / "ur10_all.cal"
UR10 = ROOT.parent / "shared" / "data" / "ur10" / "measurements_joint_configurations.csv"


def tracker_subset() -> list[str]:
    """The 23 parameters models/ur10_tracker.cal calibrates (its params, in order)."""
    text = (ROOT / "models" / "ur10_priors.cal").read_text()
    return re.findall(r"param (\w+) in", text)


@pytest.mark.slow
def test_the_ur10_with_every_parameter_free():
    """On the shipped simulated table: 25 directions seen of 33, the base absorbing the first
    joint, r2 + r3 + r4 and tz + r6 the only sums seen, alpha6 and d6 nearly not
    identifiable, and the suggested subset the 23 of ur10_tracker.cal, well conditioned."""
    a = advise(load(ALL))
    assert a.rank == 25 and len(a.names) == 33
    assert sorted(a.subset) == sorted(tracker_subset())
    assert a.subset_condition <= 300
    assert a.condition > a.subset_condition  # the faint pair is what conditions badly
    sums = {g.sum for g in a.absorbed}
    assert {"r2 + r3 + r4", "tz + r6"} <= sums
    by = {m: g.by for g in a.absorbed for m in g.members}
    assert all(all(b.startswith("base_") for b in by[m]) for m in ("alpha1", "d1", "theta1",
                                                                    "r1"))
    assert set(by["theta6"]) <= {"tx", "ty"}
    assert set(a.faint) == {"alpha6", "d6"} and max(a.faint.values()) < 1
    text = render(a)
    assert "only r2 + r3 + r4 is seen" in text and "rank 25 of 33" in text


def test_rank_counts_what_the_bounds_can_see(write_model):
    """Two exact copies (only a + b is seen) and a parameter whose effect over its domain is a
    millionth of the error bound (not seen): neither counts; a third, well seen, does."""
    rows = "\n".join(f"{x!r};{2 * x + 0.5!r}" for x in np.linspace(-1, 1, 12).tolist())
    path = write_model("""
table m = "d.csv" (separator = ";") { x : +- 1e-9; y : +- 0.1; }
param a in 1 +- 0.5; param b in 0 +- 0.5; param c in 0.5 +- 0.5; param f in 0 +- 1e-7;
for k in 1..rows(m) { (a + b) * m.x[k] + c + f * m.x[k]^2 == m.y[k]; }
""", files={"d.csv": "x;y\n" + rows + "\n"})
    a = advise(load(path))
    assert a.rank == 2
    assert all(v >= SEEN for v in a.singular_values[:2])
    assert {g.sum for g in a.absorbed} == {"a + b"}
    assert a.unseen == ["f"] and not a.faint
    assert a.subset == ["a", "c"] and a.subset_condition <= COND_MAX


@pytest.mark.slow
def test_identify_json(calibc):
    out = subprocess.run([*calibc, "identify", str(ALL), "--json"], capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert data["rank"] == 25 and data["parameters"] == 33
    assert len(data["suggested_subset"]["parameters"]) == 23
    assert data["suggested_subset"]["condition_number"] <= 300


@pytest.mark.slow
@pytest.mark.skipif(not UR10.exists(), reason=f"the public UR10 data set is not at "
                    f"{UR10.parent} (make fetch-ur10 downloads it; docs/real-data.md)")
def test_the_public_data_every_15th_row():
    from calib_dsl.elaborate.elaborator import Inputs
    from calib_dsl.elaborate.rows import Selection, parse_ranges

    inputs = Inputs(data={"m": UR10}, rows={"m": Selection(parse_ranges("1..1495:15"), ())})
    a = advise(load(ALL, inputs=inputs))
    assert a.rank == 25
    assert len(a.subset) == 23 and a.subset_condition <= 300
    assert "r2 + r3 + r4" in {g.sum for g in a.absorbed}
