"""Shaving (inner/shave.py): the gap between an end of the result and the certified inner
bound, contracted as a slice of its own. It must never cut a solution (every point that
satisfies the rows stays inside; on random robots the truth stays inside), it must narrow
where the gap is the relaxation's (points round a circle), and it keeps to its count and
its time budget."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib_dsl.cli import main
from calib_dsl.inner.bounds import inner_bounds
from calib_dsl.inner.shave import candidates, shave, worst_end
from calib_dsl.pipeline import load, solve
from calib_dsl.relax.layout import independents
from calib_dsl.settings import DEFAULT
from calib_dsl.strategy.tight import solve_tight
from tests.relax.test_linearize import random_robot, robot_draws

EVERY = replace(DEFAULT, shave_above=1.0)  # every unknown with a gap, whatever its ratio
CIRCLE = """param cx in [-10, 10]; param cy in [-10, 10]; param radius in [0, 10];
table m = "c.csv" { x, y : +- E; }
for k in 1..rows(m) { sqr(m.x[k] - cx) + sqr(m.y[k] - cy) == sqr(radius); }
"""


def write_circle(tmp: Path, seed: int = 0, points: int = 5, noise: float = 0.04,
                 e: float = 0.05) -> np.ndarray:
    """tmp/circle.cal and its data: points round a circle of radius 3 about (2, -1), each
    coordinate off by up to `noise`, each read to +-e (the result of the default case is
    1.10-1.12 times its inner intervals). Returns the cells."""
    rng = np.random.default_rng(seed)
    angles = 0.3 + 2 * np.pi * np.arange(points) / points
    cells = np.array([(2 + 3 * np.cos(t) + rng.uniform(-noise, noise),
                       -1 + 3 * np.sin(t) + rng.uniform(-noise, noise)) for t in angles])
    rows = "\n".join(f"{float(x)!r},{float(y)!r}" for x, y in cells)
    (tmp / "c.csv").write_text("x,y\n" + rows + "\n")
    (tmp / "circle.cal").write_text(CIRCLE.replace("E", repr(e)))
    return cells


def _circle(tmp: Path, seed: int, points: int, noise: float, e: float):
    """write_circle's program, its cells, the solve and the inner bounds."""
    cells = write_circle(tmp, seed, points, noise, e)
    prog = load(tmp / "circle.cal")
    sol = solve(prog)
    assert sol.status == "contracted"
    return prog, cells, sol, inner_bounds(prog, sol.lo, sol.hi)


def _solutions(cxy: np.ndarray, cells: np.ndarray, e: float) -> np.ndarray:
    """Points (cx, cy, radius) that satisfy every row, for the centres `cxy` that have any:
    each centre's radii run from the largest distance to the nearest point of a cell's box
    to the smallest distance to its farthest point; the smallest, the largest and the middle
    one are taken, kept a margin far above rounding inside (the boxes shrunk by 1e-6 of e,
    the radii by 1e-9)."""
    e = e * (1 - 1e-6)
    near = np.zeros(len(cxy))
    far = np.full(len(cxy), np.inf)
    for cell in cells:
        gap = np.maximum(np.abs(cxy - cell) - e, 0.0)
        near = np.maximum(near, np.hypot(gap[:, 0], gap[:, 1]))
        reach = np.abs(cxy - cell) + e
        far = np.minimum(far, np.hypot(reach[:, 0], reach[:, 1]))
    some = near * (1 + 1e-9) < far * (1 - 1e-9)
    radii = [near[some] * (1 + 1e-9), far[some] * (1 - 1e-9), 0.5 * (near[some] + far[some])]
    return np.vstack([np.column_stack([cxy[some], r]) for r in radii])


@pytest.mark.slow
@settings(max_examples=4, deadline=None,  # 15 in bench/checks/test_soundness_full.py
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 10_000), points=st.integers(4, 7),
       noise=st.floats(0.005, 0.045), e=st.sampled_from([0.05, 0.08]))
def test_shaving_keeps_every_point_that_satisfies_the_rows(tmp_path_factory, seed, points,
                                                           noise, e):
    tmp = tmp_path_factory.mktemp("shave")
    prog, cells, sol, inner = _circle(tmp, seed, points, noise, e)
    ind = independents(prog)
    new, done = shave(prog, sol, inner.lo, inner.hi, EVERY)
    assert np.all(sol.lo <= new.lo) and np.all(new.hi <= sol.hi)
    assert np.all(new.lo[ind] <= inner.lo) and np.all(inner.hi <= new.hi[ind])
    # solutions at centres drawn over the solve's box, half of them with a coordinate in a
    # gap between the result and the inner bounds, each with its smallest and largest
    # radius: every one must still be in the shaved box
    rng = np.random.default_rng(seed)
    lo, hi, a, b = sol.lo[ind][:2], sol.hi[ind][:2], inner.lo[:2], inner.hi[:2]
    cxy = rng.uniform(lo, hi, size=(100_000, 2))
    half = np.arange(len(cxy) // 2)
    axis = rng.integers(0, 2, size=len(half))
    upper = rng.uniform(0, 1, size=len(half)) < 0.5
    cxy[half, axis] = np.where(upper, rng.uniform(b[axis], hi[axis]),
                               rng.uniform(lo[axis], a[axis]))
    found = _solutions(cxy, cells, e)
    beyond = np.any((found < inner.lo) | (found > inner.hi), axis=1)
    assert beyond.sum() >= 20  # solutions in the gaps: the check has teeth
    assert np.all(new.lo[ind] <= found) and np.all(found <= new.hi[ind])


def test_shaving_narrows_the_circle_to_its_inner_bounds(tmp_path):
    """Five points, noise 0.04 against a bound of 0.05: the result is 1.10-1.12 times the
    inner intervals, shaved within 1.03 of them."""
    prog, _, sol, inner = _circle(tmp_path, 0, 5, 0.04, 0.05)
    ind = independents(prog)
    before = (sol.hi[ind] - sol.lo[ind]) / (inner.hi - inner.lo)
    new, done = shave(prog, sol, inner.lo, inner.hi, EVERY)
    after = (new.hi[ind] - new.lo[ind]) / (inner.hi - inner.lo)
    assert np.all(before > 1.08)
    assert done is not None and set(done.names) == {"cx", "cy", "radius"}
    assert np.all(after < 1.03), after


@pytest.mark.slow
@settings(max_examples=2, deadline=None,  # 8 in bench/checks/test_soundness_full.py
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(**robot_draws(st.integers(6, 14)))
def test_shaved_random_robots_hold_the_truth(tmp_path_factory, seed, joints, rows, formulation):
    sim = random_robot(tmp_path_factory.mktemp("shave"), seed, joints, rows, formulation)
    prog = sim.prog
    sol = solve_tight(prog, combinations=False)
    assert sol.status == "contracted"
    inner = inner_bounds(prog, sol.lo, sol.hi)
    new, _ = shave(prog, sol, inner.lo, inner.hi, EVERY)
    for k, truth in zip(independents(prog), sim.p_true, strict=True):
        assert new.lo[k] <= truth <= new.hi[k], prog.slots.names[k]


def test_candidates_are_the_loosest_above_the_ratio_at_most_the_count():
    lo, hi = np.zeros(5), np.array([1.0, 1.0, 1.0, 1.0, 1.0])
    a = np.array([0.0, 0.02, 0.1, np.nan, 0.3])  # ratios 1, 1/0.96, 1/0.8, none, 1/0.4
    b = 1.0 - a
    s = replace(DEFAULT, shave_above=1.05, shave_unknowns=8)
    assert candidates(lo, hi, a, b, s) == [4, 2]
    assert candidates(lo, hi, a, b, replace(s, shave_unknowns=1)) == [4]
    assert candidates(lo, hi, a, b, replace(s, shave_above=1.01)) == [4, 2, 1]


def test_the_next_end_is_the_worst_ratios_as_the_box_is_after_each_end():
    # unknown 0: ratio 1.25, gaps 0.15 low and 0.05 high; unknown 1: ratio 1.2, gaps 0.1
    # low and 1/15 high
    lo, hi = np.zeros(2), np.ones(2)
    a, b = np.array([0.15, 0.1]), np.array([0.95, 0.1 + 1 / 1.2])
    s = replace(DEFAULT, shave_above=1.05, shave_unknowns=8, shave_min_gap=0.005)
    assert worst_end(lo, hi, a, b, [], s) == (0, 0)  # the worst ratio, its wider gap
    lo[0] = 0.14  # its low end shaved: ratio 0.86 / 0.8 = 1.075, now below unknown 1's
    assert worst_end(lo, hi, a, b, [(0, 0)], s) == (1, 0)
    assert worst_end(lo, hi, a, b, [(0, 0), (1, 0)], s) == (1, 1)
    # at most shave_unknowns begun: the first one's other end, not a third unknown's
    assert worst_end(lo, hi, a, b, [(0, 0)], replace(s, shave_unknowns=1)) == (0, 1)
    # an end already shaved is not shaved again; a gap under shave_min_gap is left alone
    assert worst_end(lo, hi, a, b, [(0, 0), (0, 1), (1, 0), (1, 1)], s) is None
    assert worst_end(lo, hi, a, b, [(1, 0), (1, 1)], replace(s, shave_min_gap=0.06)) is None


def test_no_time_and_no_count_shave_nothing(tmp_path):
    prog, _, sol, inner = _circle(tmp_path, 0, 5, 0.04, 0.05)
    assert shave(prog, sol, inner.lo, inner.hi, EVERY, budget=0.0) == (sol, None)
    assert shave(prog, sol, inner.lo, inner.hi, replace(EVERY, shave_unknowns=0)) == (sol, None)


@pytest.mark.slow
def test_cli_reports_what_it_shaved(tmp_path):
    _circle(tmp_path, 0, 5, 0.04, 0.05)
    model = str(tmp_path / "circle.cal")

    def run(*args: str) -> str:
        done = CliRunner().invoke(main, ["solve", model, *args])
        assert done.exit_code == 0, done.output
        return done.output

    shaved, plain = run("--shave", "3"), run("--shave", "0")
    line = next(x for x in shaved.splitlines() if x.startswith("shaved: "))
    assert set(line.split("(")[0].split()[1:]) == {"cx", "cy", "radius"}
    assert "shaved" not in plain
    assert "shaved: " in run()  # by default: the loosest first (the first end always runs)
    assert "shaved" not in run("--strategy", "hc4", "--inner")  # propagation alone, as asked
    assert "shaved: " in run("--strategy", "hc4", "--shave", "1")  # asked: inner bounds too
    assert "shaving: not without the inner bounds" in run("--no-inner", "--shave", "1")
    assert '"shaved"' in run("--shave", "1", "--json", "-")


def test_shaving_keeps_to_the_sweeps_left_and_to_the_time_budget(tmp_path):
    prog, _, sol, inner = _circle(tmp_path, 0, 5, 0.04, 0.05)
    for cap in (sol.sweeps + 1, sol.sweeps + 3):
        _, done = shave(prog, sol, inner.lo, inner.hi, EVERY, max_sweeps=cap)
        assert done is not None and done.work.sweeps <= cap - sol.sweeps
    assert shave(prog, sol, inner.lo, inner.hi, EVERY, max_sweeps=sol.sweeps) == (sol, None)
    _, one = shave(prog, sol, inner.lo, inner.hi, EVERY, budget=1e-9)
    _, every = shave(prog, sol, inner.lo, inner.hi, EVERY, budget=1e9)
    assert one is not None and every is not None
    assert one.work.lp_rounds < every.work.lp_rounds  # the first end only, against all six


@pytest.mark.slow
def test_a_program_in_chunks_is_shaved_by_default_only_after_fine_rounds(tmp_path,
                                                                       monkeypatch):
    """A program relaxed in chunks of rows: by default (a budget) only where the solve ran
    fine rounds; asked (no budget), always."""
    import calib_dsl.inner.shave as module
    from calib_dsl.elaborate.elaborator import Inputs
    from calib_dsl.elaborate.rows import Selection, parse_ranges

    root = Path(__file__).resolve().parents[2]
    prog = load(root / "models" / "ur10_tracker.cal",  # (its shipped simulated table)
                inputs=Inputs(rows={"m": Selection(parse_ranges("1..100:10"), ())}))
    assert prog.rows is not None  # (the loop over the rows, compiled once)
    sol = solve_tight(prog, combinations=False)
    inner = inner_bounds(prog, sol.lo, sol.hi)
    monkeypatch.setattr(module, "CHUNK_SLOTS", 1)  # (a chunk a row)
    plain = replace(sol, work=replace(sol.work, fine_rounds=0))
    fine = replace(sol, work=replace(sol.work, fine_rounds=2))
    one = replace(EVERY, shave_unknowns=1)
    assert shave(prog, plain, inner.lo, inner.hi, one, budget=1e-9) == (plain, None)
    assert shave(prog, plain, inner.lo, inner.hi, one)[1] is not None  # (asked)
    assert shave(prog, fine, inner.lo, inner.hi, one, budget=1e-9)[1] is not None
    monkeypatch.setattr(module, "CHUNK_SLOTS", 10**9)  # (one piece: as before)
    assert shave(prog, plain, inner.lo, inner.hi, one, budget=1e-9)[1] is not None


def test_the_api_says_what_it_shaved(tmp_path):
    import calib_dsl

    write_circle(tmp_path)
    problem = calib_dsl.load(tmp_path / "circle.cal")
    shaved = calib_dsl.solve(problem, shave=3)
    plain = calib_dsl.solve(problem, shave=0)
    assert sorted(shaved.shaved) == ["cx", "cy", "radius"] and plain.shaved == ()
    for name in ("cx", "cy", "radius"):
        (a, b), (c, d) = shaved[name].result, plain[name].result
        assert c <= a and b <= d and (b - a) < 0.97 * (d - c)
