"""Shaving (strategy/shave.py): the gap between an end of the result and the certified inner
bound, contracted as a slice of its own. It must never cut a solution (every point that
satisfies the rows stays inside; on random robots the truth stays inside), it must narrow
where the gap is the relaxation's (points round a circle), and it keeps to its count and
its time budget."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib_dsl.analysis.inner import inner_bounds
from calib_dsl.cli import main
from calib_dsl.pipeline import load, solve
from calib_dsl.relax.layout import independents
from calib_dsl.settings import DEFAULT
from calib_dsl.strategy.shave import candidates, shave
from calib_dsl.strategy.tight import solve_tight
from tests.relax.test_linearize import clean_version, robot_source, simulate_cal

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


def _on_every_circle(p: np.ndarray, cells: np.ndarray, e: float) -> np.ndarray:
    """Which points p (rows cx, cy, radius) put some point of every cell's box (shrunk by a
    margin far above rounding) on their circle: the radius lies between the box's nearest
    and farthest distance from the centre."""
    e = e * (1 - 1e-6)
    ok = np.ones(len(p), dtype=bool)
    for x, y in cells:
        near = [np.maximum(np.maximum(c - e - q, q - c - e), 0.0)
                for c, q in ((x, p[:, 0]), (y, p[:, 1]))]
        far = [np.abs(c - q) + e for c, q in ((x, p[:, 0]), (y, p[:, 1]))]
        r2 = p[:, 2] ** 2
        ok &= (near[0] ** 2 + near[1] ** 2 < r2 * (1 - 1e-9)) \
            & (r2 * (1 + 1e-9) < far[0] ** 2 + far[1] ** 2)
    return ok


@settings(max_examples=15, deadline=None,
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
    # points drawn over the solve's box and in its margins, beyond the inner bounds: every
    # one that satisfies the rows must still be inside the shaved box
    rng = np.random.default_rng(seed)
    lo, hi = sol.lo[ind], sol.hi[ind]
    draws = rng.uniform(lo, hi, size=(200_000, 3))
    edge = rng.integers(0, 3, size=len(draws))
    beyond = rng.uniform(0, 1, size=len(draws)) < 0.5
    gap_lo = rng.uniform(lo[edge], inner.lo[edge])
    gap_hi = rng.uniform(inner.hi[edge], hi[edge])
    draws[np.arange(len(draws)), edge] = np.where(beyond, gap_lo, gap_hi)
    fits = draws[_on_every_circle(draws, cells, e)]
    assert np.all(new.lo[ind] <= fits) and np.all(fits <= new.hi[ind])


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


@settings(max_examples=8, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 10_000), joints=st.integers(1, 3), rows=st.integers(6, 14),
       formulation=st.sampled_from(["matrix", "rotation"]))
def test_shaved_random_robots_hold_the_truth(tmp_path_factory, seed, joints, rows, formulation):
    rng = np.random.default_rng(seed)
    source = robot_source(rng, joints, 1e-6, 1e-4, spatial=bool(seed % 2))
    sim = simulate_cal(tmp_path_factory.mktemp("shave"), source, clean_version(source),
                       rows, seed, formulation)
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


def test_no_time_and_no_count_shave_nothing(tmp_path):
    prog, _, sol, inner = _circle(tmp_path, 0, 5, 0.04, 0.05)
    assert shave(prog, sol, inner.lo, inner.hi, EVERY, budget=0.0) == (sol, None)
    assert shave(prog, sol, inner.lo, inner.hi, replace(EVERY, shave_unknowns=0)) == (sol, None)


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
    assert "shaved" not in run("--strategy", "hc4", "--inner")  # propagation alone, as asked
    assert '"shaved"' in run("--shave", "1", "--json", "-")
