"""`param x in lsq +- w`: the domain centred on the least-squares estimate of the data at hand,
stated as a prior; the truth inside on random draws."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.pipeline import load, solve

CIRCLE = """param cx in lsq +- 0.5;
param cy in lsq({start}) +- 0.5;
param radius in {radius} +- 1;
table m = "c.csv" {{ x, y : +- 1e-3; }}
for k in 1..rows(m) {{ sqr(m.x[k] - cx) + sqr(m.y[k] - cy) == sqr(radius); }}
"""


def write_circle(tmp_path, cx, cy, radius, rng, start="0"):
    """Points of a circle; cx's search starts at 0, cy's at `start` (least squares finds a
    circle's centre from a start within about its radius)."""
    t = rng.uniform(0, 2 * np.pi, 20)
    noise = rng.uniform(-1e-3, 1e-3, (2, 20))
    x, y = cx + radius * np.cos(t) + noise[0], cy + radius * np.sin(t) + noise[1]
    (tmp_path / "c.csv").write_text("x,y\n" + "".join(f"{float(a)!r},{float(b)!r}\n"
                                                      for a, b in zip(x, y, strict=True)))
    path = tmp_path / "m.cal"
    path.write_text(CIRCLE.format(start=start, radius=radius))
    return path


@settings(max_examples=20, deadline=None)
@given(st.floats(-2, 2), st.floats(-50, 50), st.floats(5, 20), st.integers(0, 2**31))
def test_lsq_domains_are_centred_on_the_data_and_hold_the_truth(tmp_path_factory, cx, cy, r,
                                                               seed):
    tmp = tmp_path_factory.mktemp("c")
    path = write_circle(tmp, cx, cy, r, np.random.default_rng(seed), start=repr(cy + 1.0))
    prog = load(path)
    assert set(prog.centred) == {"cx", "cy"}
    for name, truth in (("cx", cx), ("cy", cy)):
        lo, hi = prog.domains[name]
        centre, w = prog.centred[name]
        assert w == 0.5 and lo == centre - 0.5 and hi == centre + 0.5
        assert abs(centre - truth) < 0.01  # the estimate is near the truth
    sol = solve(prog)
    assert sol.status == "contracted"
    for name, truth in (("cx", cx), ("cy", cy), ("radius", r)):
        i = prog.slots.names.index(name)
        assert sol.lo[i] <= truth <= sol.hi[i]


@pytest.mark.slow
def test_the_report_states_the_prior(tmp_path, calibc):
    path = write_circle(tmp_path, 3.0, -2.0, 5.0, np.random.default_rng(1))
    out = subprocess.run([*calibc, "solve", str(path), "--json", "-"], capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    prior = data["parameters"]["cx"]["prior"]
    assert abs(prior["lsq"] - 3.0) < 0.01 and prior["half_width"] == 0.5
    assert "prior" not in data["parameters"]["radius"]
    text = subprocess.run([*calibc, "solve", str(path)], capture_output=True, text=True,
                          timeout=120).stdout
    assert "centred on the least-squares estimate of these data" in text


@pytest.mark.parametrize("domain,message", [
    ("lsq +- 0", "must be finite and > 0"),
    ("lsq(1, 2) +- 1", "lsq(start) takes one value"),
])
def test_bad_lsq_domains(tmp_path, domain, message):
    (tmp_path / "c.csv").write_text("x,y\n1,2\n")
    path = tmp_path / "m.cal"
    path.write_text(f"param cx in {domain};\ntable m = \"c.csv\" {{ x, y : +- 1; }}\n"
                    "for k in 1..rows(m) { cx == m.x[k]; }\n")
    with pytest.raises(CalError, match=message.replace("(", r"\(").replace(")", r"\)")):
        load(path)


@pytest.mark.slow
def test_an_estimate_started_on_a_sample_is_the_estimate_of_all_rows(tmp_path, monkeypatch):
    """Over 250 simulated UR10 configurations the least-squares estimate is first fitted on
    a spread sample of 100, then polished on all: the same estimate as fitting all rows from
    the start (to 1e-6 mm and 1e-9 rad)."""
    from pathlib import Path

    from calib_dsl.analysis import lsq
    from calib_dsl.settings import SamplingSettings
    from calib_dsl.studies.simulate import simulate

    model = Path(__file__).resolve().parents[2] / "models" / "ur10_simulated.cal"
    table = tmp_path / "sim.csv"
    simulate(model, 250, 3, out_csv=table)
    prog = load(model, data=table)
    fits = []
    fit = lsq._fit

    def recorded(prog, start, evaluations, rows):
        fits.append(None if rows is None else len(rows))
        return fit(prog, start, evaluations, rows)

    monkeypatch.setattr(lsq, "_fit", recorded)
    sampled = lsq.estimate(prog)  # from the middle of the (centred) domains
    assert fits == [100, None]
    whole = lsq.estimate(prog, sampling=SamplingSettings(lsq_min_rows=10**6))
    assert fits == [100, None, None]
    assert sampled.converged and whole.converged
    assert np.allclose(sampled.values, whole.values, rtol=0, atol=1e-6)
