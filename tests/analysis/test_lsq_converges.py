"""Least squares converges from nominal on any robot within its priors (analysis/lsq.py): a
simulated UR5 whose every parameter is drawn anywhere in its domain, millimetres from
nominal, measured exactly in its joints and to +- e in position. The issue's case, 1000
rows, runs in bench/checks/test_lsq_1000_rows.py."""

from __future__ import annotations

import re
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib_dsl.analysis.lsq import estimate
from calib_dsl.compile.chunks import spread_rows
from calib_dsl.pipeline import load
from calib_dsl.relax.layout import independents
from calib_dsl.settings import SamplingSettings
from tests.simulated_ur5 import JOINTS, PARAMS, header, simulate_rows

NOMINAL = {"ur5_alpha2": np.pi / 2, "ur5_alpha5": np.pi / 2, "ur5_d3": -425.0,
           "ur5_d4": -392.25, "ur5_r5": 94.65}
E = 0.05


def _centre(text: str) -> float:
    return float(text) if re.fullmatch(r"-?[0-9.]+", text) else NOMINAL.get(text, 0.0)


def _campaign(tmp: Path, shares: list[float], rows: int, seed: int,
              batched: bool) -> tuple[Path, dict[str, float]]:
    """A robot at `shares` of its half-widths from nominal, and its model over `rows`
    simulated configurations (joints written to 9 decimals when `batched`: cells that are
    not floats, so the loop is compiled once and least squares starts on a sample)."""
    true = {name: _centre(c) + s * w
            for (name, (c, w, _)), s in zip(PARAMS.items(), shares, strict=True)}
    data = simulate_rows(tmp, rows, seed, E, true)
    cols = ["q1", "q2", "q3", "q4", "q5", "q6", "x", "y", "z"]
    with open(tmp / "data.csv", "w", encoding="utf-8") as f:
        f.write(",".join(cols) + "\n")
        for r in data:
            f.write(",".join(f"{r[c]:.9f}" if batched and c[0] == "q" else repr(r[c])
                             for c in cols) + "\n")
    path = tmp / "robot.cal"
    path.write_text(header(E, true) + 'table m = "data.csv" {\n  q1, q2, q3, q4, q5, q6 : +- 0;'
                    "\n  x, y, z : +- e;\n}\nfor k in 1..rows(m) {\n"
                    f"  ur5({JOINTS}) at (tx, ty, tz) == (m.x[k], m.y[k], m.z[k]);\n}}\n",
                    encoding="utf-8")
    return path, true


def _check(path: Path, true: dict[str, float], sampling: SamplingSettings | None = None) -> None:
    prog = load(path)
    ind = independents(prog)
    lo, hi = prog.slots.lo[ind], prog.slots.hi[ind]
    est = estimate(prog, start=0.5 * (lo + hi), max_evaluations=200,  # from nominal
                   sampling=sampling)
    assert est.converged
    got = dict(zip(est.names, est.values.tolist(), strict=True))
    for name, (_, w, _) in PARAMS.items():  # within a small share of the prior's width
        assert abs(got[name] - true[name]) <= 0.02 * w, (name, got[name], true[name])


shares = st.lists(st.floats(-0.95, 0.95), min_size=len(PARAMS), max_size=len(PARAMS))


@pytest.mark.slow
@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(shares, st.integers(0, 10_000))
def test_least_squares_finds_any_robot_within_its_priors(shares: list[float], seed: int) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        _check(*_campaign(Path(tmp), shares, 40, seed, batched=False))


@settings(max_examples=3, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(shares, st.integers(0, 10_000))
def test_least_squares_from_a_sample_then_on_all_rows(shares: list[float], seed: int) -> None:
    """Over 100 configurations compiled once: a sample of 40 first (the default's least
    sample, 100, needs more than 200 rows: the size does not change the path), then every
    row."""
    with tempfile.TemporaryDirectory() as tmp:
        path, true = _campaign(Path(tmp), shares, 100, seed, batched=True)
        prog = load(path)
        assert prog.rows is not None  # (the sample's path is the one tested)
        sampling = SamplingSettings(lsq_min_rows=40)
        assert spread_rows(prog, 40) is not None
        _check(path, true, sampling)
