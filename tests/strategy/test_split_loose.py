"""The split of a loose result (strategy/split.py, `split_loose`): after shaving, an unknown
still loose against its certified inner interval has the unknowns that kept (nearly) their
whole domain cut in halves, each contracted, the hull kept. It must never lose a solution
(on random robots the truth stays inside), it fires only on a loose result and an unknown
left wide, and it keeps to its count and budget."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib_dsl.inner.bounds import inner_bounds
from calib_dsl.pipeline import load, solve
from calib_dsl.relax.layout import independents
from calib_dsl.settings import DEFAULT
from calib_dsl.settings_strategy import LooseSettings
from calib_dsl.strategy.split import loose, split_loose, whole_domains
from calib_dsl.strategy.tight import solve_tight
from tests.relax.test_linearize import random_robot, robot_draws

# every unknown counts as loose and as wide: the rule always fires
FORCED = replace(DEFAULT, loose=LooseSettings(above=1.0, whole=0.0, tried=2))

# a circle whose centre's x is cx + 0.01 w: the data see w a hundred times fainter than cx,
# and w keeps its whole domain
FAINT = """param cx in [-10, 10]; param cy in [-10, 10]; param radius in [0, 10];
param w in [-1, 1];
table m = "c.csv" { x, y : +- 0.05; }
for k in 1..rows(m) { sqr(m.x[k] - cx - 0.01 * w) + sqr(m.y[k] - cy) == sqr(radius); }
"""


def _faint(tmp: Path):
    rng = np.random.default_rng(3)
    angles = 0.3 + 2 * np.pi * np.arange(6) / 6
    rows = "\n".join(f"{float(2 + 3 * np.cos(t) + rng.uniform(-0.04, 0.04))!r},"
                     f"{float(-1 + 3 * np.sin(t) + rng.uniform(-0.04, 0.04))!r}" for t in angles)
    (tmp / "c.csv").write_text("x,y\n" + rows + "\n")
    (tmp / "faint.cal").write_text(FAINT)
    prog = load(tmp / "faint.cal")
    sol = solve(prog)
    assert sol.status == "contracted"
    return prog, sol, inner_bounds(prog, sol.lo, sol.hi)


def test_the_unknown_left_its_whole_domain_is_the_one_cut(tmp_path):
    prog, sol, inner = _faint(tmp_path)
    w = prog.slots.names.index("w")
    assert sol.hi[w] - sol.lo[w] > DEFAULT.loose.whole * 2  # kept (nearly) its domain
    assert whole_domains(prog, sol.lo, sol.hi, DEFAULT) == [w]
    loose_only = replace(DEFAULT, loose=replace(DEFAULT.loose, above=1.0))
    out = split_loose(prog, (sol.lo, sol.hi), (inner.lo, inner.hi), loose_only, None, 1e-5,
                      1000)
    assert out.names == ("w",)
    assert np.all(sol.lo <= out.lo) and np.all(out.hi <= sol.hi)
    ind = independents(prog)  # the certified points are solutions: still inside
    assert np.all(out.lo[ind] <= inner.lo) and np.all(inner.hi <= out.hi[ind])


def test_nothing_loose_or_no_time_cuts_nothing(tmp_path):
    prog, sol, inner = _faint(tmp_path)
    ind = independents(prog)
    tight = (sol.lo[ind], sol.hi[ind])  # inner intervals equal to the result: ratio 1
    out = split_loose(prog, (sol.lo, sol.hi), tight, DEFAULT, None, 1e-5, 1000)
    assert out.names == () and np.array_equal(out.lo, sol.lo) and np.array_equal(out.hi, sol.hi)
    out = split_loose(prog, (sol.lo, sol.hi), (inner.lo, inner.hi), FORCED, 0.0, 1e-5, 1000)
    assert out.names == ()
    out = split_loose(prog, (sol.lo, sol.hi), (inner.lo, inner.hi), FORCED, None, 1e-5, 0)
    assert out.names == ()  # no sweeps left


def test_loose_measures_the_ratio_over_certified_intervals_only():
    lo, hi = np.zeros(3), np.ones(3)
    assert loose(lo, hi, (np.array([0.0, np.nan, 0.0]), np.array([0.9, np.nan, 1.0])), 1.1)
    assert not loose(lo, hi, (np.array([0.0, np.nan, 0.0]), np.array([0.95, np.nan, 1.0])),
                     1.1)


def _halved_holds_the_truth(tmp: Path, seed: int, joints: int, rows: int,
                            formulation: str) -> None:
    sim = random_robot(tmp, seed, joints, rows, formulation)
    prog = sim.prog
    sol = solve_tight(prog, combinations=False)
    assert sol.status == "contracted"
    inner = inner_bounds(prog, sol.lo, sol.hi)
    out = split_loose(prog, (sol.lo, sol.hi), (inner.lo, inner.hi), FORCED, None, 1e-5, 1000)
    assert len(out.names) == min(2, len(independents(prog)))  # forced: it fires
    assert np.all(sol.lo <= out.lo) and np.all(out.hi <= sol.hi)
    for k, truth in zip(independents(prog), sim.p_true, strict=True):
        assert out.lo[k] <= truth <= out.hi[k], prog.slots.names[k]


def test_halves_of_a_random_robot_hold_the_truth(tmp_path):
    _halved_holds_the_truth(tmp_path, 7, 2, 8, "matrix")


@settings(max_examples=5, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(**robot_draws(st.integers(6, 14)))
def test_halves_of_random_robots_hold_the_truth(tmp_path_factory, seed, joints, rows,
                                                formulation):
    _halved_holds_the_truth(tmp_path_factory.mktemp("loose"), seed, joints, rows, formulation)


def _inner_at_ratio(lo: np.ndarray, hi: np.ndarray, ratio: float):
    """Inner intervals `ratio` times narrower than [lo, hi], centred (what `loose` reads)."""
    mid, half = (lo + hi) / 2, (hi - lo) / (2 * ratio)
    return mid - half, mid + half


@given(st.floats(1.0, 1.19))
@settings(max_examples=6, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_a_result_within_the_promise_is_not_cut(tmp_path, ratio):
    prog, sol, _ = _faint(tmp_path)
    ind = independents(prog)
    out = split_loose(prog, (sol.lo, sol.hi), _inner_at_ratio(sol.lo[ind], sol.hi[ind], ratio),
                      DEFAULT, None, 1e-5, 1000)
    assert out.names == () and np.array_equal(out.lo, sol.lo)


def test_a_result_beyond_the_promise_is_cut(tmp_path):
    prog, sol, _ = _faint(tmp_path)
    ind = independents(prog)
    inside = _inner_at_ratio(sol.lo[ind], sol.hi[ind], DEFAULT.loose.above * 1.01)
    out = split_loose(prog, (sol.lo, sol.hi), inside, DEFAULT, None, 1e-5, 1000)
    assert out.names == ("w",)
    assert np.all(sol.lo <= out.lo) and np.all(out.hi <= sol.hi)


def test_the_report_and_json_name_the_unknowns_halved(tmp_path):
    from calib_dsl.inner.shave import Shaved
    from calib_dsl.report.as_json import result_json
    from calib_dsl.report.extras import Extras
    from calib_dsl.report.text import render_summary
    from calib_dsl.strategy.contractor import Work

    prog, sol, _ = _faint(tmp_path)
    extra = Extras()
    extra.shaved = Shaved(("cx",), 0.5, Work(), ("w",))
    assert "halved: w (" in render_summary(prog, sol, "tight", extra)
    assert result_json(prog, sol, "tight", extra)["shaved"]["halved"] == ["w"]
    extra.shaved = Shaved(("cx",), 0.5, Work())
    assert "halved" not in render_summary(prog, sol, "tight", extra)
    assert result_json(prog, sol, "tight", extra)["shaved"]["halved"] == []


def test_a_result_not_loose_ranks_no_unknown(tmp_path, monkeypatch):
    """Ranking the wide unknowns costs a relaxation per half: not run where nothing is cut."""
    import calib_dsl.strategy.split as split

    prog, sol, _ = _faint(tmp_path)
    ind = independents(prog)
    monkeypatch.setattr(split, "whole_domains", lambda *a: pytest.fail("ranked"))
    out = split_loose(prog, (sol.lo, sol.hi), _inner_at_ratio(sol.lo[ind], sol.hi[ind], 1.1),
                      DEFAULT, None, 1e-5, 1000)
    assert out.names == ()
