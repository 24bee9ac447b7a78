"""Certified inner bounds: every witness point satisfies every constraint when checked
independently in exact arithmetic (rationals for a line fit, 60-digit mpmath for the RX90), lies
inside the outer box, and the inner intervals reach the hull where it is known."""

from __future__ import annotations

import copy
import json
import math
from fractions import Fraction
from pathlib import Path

import mpmath
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.optimize import linprog

from calib_dsl.analysis.certify_point import check_point, check_points, reading_slots
from calib_dsl.cli import main
from calib_dsl.elaborate.elaborator import Inputs
from calib_dsl.inner.bounds import inner_bounds
from calib_dsl.pipeline import load, solve
from calib_dsl.relax.layout import independents
from calib_dsl.studies.simulate import simulate
from tests.relax.test_linearize import random_robot, robot_draws

ROOT = Path(__file__).resolve().parents[2]

LINE = """const e = 0.2;
table m = "d.csv" { x : +- 0; y : +- e; }
param a in [-6, 6]; param b in [-6, 6];
for k in 1..rows(m) { a * m.x[k] + b == m.y[k]; }
"""


def _hull(x: np.ndarray, y: np.ndarray, e: float, k: int, sign: float) -> float:
    """The exact problem's extreme of unknown k (a polytope: an LP, to its tolerance)."""
    ones = np.ones_like(x)
    A = np.vstack([np.c_[x, ones], -np.c_[x, ones]])
    c = np.zeros(2)
    c[k] = -sign
    res = linprog(c, A_ub=A, b_ub=np.r_[y + e, e - y], bounds=[(-6, 6)] * 2, method="highs")
    return sign * -res.fun


coord = st.floats(-3, 3, allow_nan=False, width=32)


@pytest.mark.slow
@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(coord, coord), min_size=2, max_size=8, unique_by=lambda t: t[0]),
       st.floats(0.05, 2.0))
def test_line_witnesses_hold_exactly_and_reach_the_hull(tmp_path_factory, rows, e):
    tmp = tmp_path_factory.mktemp("line")
    cells = [(repr(float(x)), repr(float(y))) for x, y in rows]
    (tmp / "d.csv").write_text("x,y\n" + "\n".join(f"{x},{y}" for x, y in cells) + "\n")
    (tmp / "line.cal").write_text(LINE)
    prog = load(tmp / "line.cal", inputs=Inputs(consts={"e": repr(e)}))
    sol = solve(prog)
    if sol.status == "infeasible":
        return
    inner = inner_bounds(prog, sol.lo, sol.hi)
    ind = independents(prog)
    fe = Fraction(repr(e))
    for w in inner.witnesses:
        fa, fb = (Fraction(v) for v in w.point)
        assert all(abs(fa * Fraction(x) + fb - Fraction(y)) <= fe for x, y in cells)
        assert np.all(sol.lo[ind] <= w.point) and np.all(w.point <= sol.hi[ind])
    x, y = (np.array([float(c[i]) for c in cells]) for i in (0, 1))
    for k in range(2):
        if inner.lo_at[k] < 0:
            continue
        assert inner.witnesses[inner.lo_at[k]].point[k] == inner.lo[k]
        assert inner.witnesses[inner.hi_at[k]].point[k] == inner.hi[k]
        lo, hi = _hull(x, y, e, k, -1.0), _hull(x, y, e, k, 1.0)
        if hi - lo > 1e-6 * e:  # the linear model's extremes are the hull's: reached,
            # but for the rows' aim 1e-5 of their bound inside (InnerSettings.aim), which a thin
            # hull (width << e) feels: a in [2e-5, 0.01562] where the hull is [0, 0.015625]
            assert inner.hi[k] - inner.lo[k] >= (hi - lo) * (1 - 1e-3) - 1e-4 * e


# -- the RX90: each witness checked with 60-digit arithmetic, by its own forward kinematics ----
def _mdh(alpha, d, theta, r):
    ca, sa, ct, st_ = (mpmath.cos(alpha), mpmath.sin(alpha), mpmath.cos(theta),
                       mpmath.sin(theta))
    return mpmath.matrix([[ct, -st_, 0, d], [ca * st_, ca * ct, -sa, -sa * r],
                          [sa * st_, sa * ct, ca, ca * r], [0, 0, 0, 1]])


def _rx90(p: dict, q: list) -> mpmath.matrix:
    m = _mdh(0, 0, p["theta0"], p["r0"])
    for j in range(1, 7):
        theta = (p.get(f"theta{j}", 0) if j < 6 else 0) + q[j - 1]
        m = m * _mdh(p[f"alpha{j}"], p[f"d{j}"], theta, p.get(f"r{j}", 0) if j < 6 else 0)
    return m


def _exact(text: str) -> mpmath.mpf:
    return mpmath.mpf(text)


@pytest.mark.parametrize("seed", [3, 11])
def test_rx90_witnesses_hold_at_high_precision(tmp_path, seed):
    data = tmp_path / "d.csv"
    simulate(ROOT / "models" / "rx90_lengths.cal", 10, seed, out_csv=data)
    prog = load(ROOT / "models" / "rx90_lengths.cal", inputs=Inputs(data={"m": str(data)}))
    sol = solve(prog)
    assert sol.status == "contracted"
    inner = inner_bounds(prog, sol.lo, sol.hi)
    assert inner.consistent
    ind = independents(prog)
    names = [prog.slots.names[i] for i in ind]
    # the readings' slots -> (configuration, column)
    at = reading_slots(prog)
    s = prog.slots
    where = {(s.row_keys[s.cell_row[i]][1], s.col_keys[s.cell_col[i]][1]): n
             for n, i in enumerate(at)}
    header, *lines = data.read_text().splitlines()
    cols = header.split(",")
    table = [dict(zip(cols, line.split(","), strict=True)) for line in lines]
    with mpmath.workdps(60):
        e = _exact("1e-4")
        dist = mpmath.mpf("0.1") * mpmath.sqrt(2)
        for w in inner.witnesses[:: max(1, len(inner.witnesses) // 8)]:  # a sample of them
            assert np.all(sol.lo[ind] <= w.point) and np.all(w.point <= sol.hi[ind])
            p = {n: mpmath.mpf(float(v)) for n, v in zip(names, w.point, strict=True)}
            for n in names:  # inside the declared domains exactly
                lo, hi = prog.domains[n]
                assert mpmath.mpf(lo) <= p[n] <= mpmath.mpf(hi) or math.isclose(lo, hi)
            tool = [mpmath.matrix([p[f"b{i}x"], p[f"b{i}y"], p[f"b{i}z"], 1]) for i in (1, 2, 3)]
            for k, row in enumerate(table, start=1):
                q = []
                for j in range(1, 7):
                    slot = where.get((k, f"q{j}"))
                    value = w.readings[slot] if slot is not None else float(row[f"q{j}"])
                    assert abs(mpmath.mpf(value) - _exact(row[f"q{j}"])) <= _exact("1e-5")
                    q.append(mpmath.mpf(value))
                m = _rx90(p, q)
                for i in (1, 2, 3):
                    pos = m * tool[i - 1]
                    for c, axis in enumerate("xyz"):
                        assert abs(pos[c] - _exact(row[f"a{i}{axis}"])) <= e
            for i, j in ((0, 1), (0, 2), (1, 2)):
                gap = mpmath.sqrt(sum((tool[i][c] - tool[j][c]) ** 2 for c in range(3)))
                assert abs(gap - dist) <= _exact("1e-5")


@pytest.fixture(scope="module")
def solved_a_once():
    """Test A loaded and solved once for the tests of its inner bounds (each gets a copy)."""
    prog = load(ROOT / "models" / "rx90_lengths.cal")
    return prog, solve(prog)


@pytest.fixture
def solved_a(solved_a_once):
    return copy.deepcopy(solved_a_once)


@pytest.mark.slow
@pytest.mark.parametrize("at_once", [None, 3])
def test_points_checked_together_get_each_their_own_verdict(monkeypatch, at_once, solved_a):
    """check_points (one pass for many points) says of each point what check_point says of
    it alone: random points of the RX90's box, readings anywhere in their intervals, with
    owners, some holding (the certified witnesses) and some not. The enclosures may differ
    by an ulp (arith/interval.py rounds a short array outward with nextafter, a long one by
    arithmetic: both sound), not the verdicts. With `at_once`, the pass takes that many points
    at a time (a program of many slots)."""
    from calib_dsl.analysis import certify_point

    prog, sol = solved_a
    if at_once is not None:
        monkeypatch.setattr(certify_point, "CHECK_CELLS", at_once * len(prog.slots.lo))
    ind, at = independents(prog), reading_slots(prog)
    rng = np.random.default_rng(5)
    lo, hi = prog.slots.lo[at], prog.slots.hi[at]
    inner = inner_bounds(prog, sol.lo, sol.hi)
    points = [w.point for w in inner.witnesses[:3]] + [
        sol.lo[ind] + rng.random(len(ind)) * (sol.hi[ind] - sol.lo[ind]) for _ in range(5)]
    readings = [w.readings for w in inner.witnesses[:3]] + [
        lo + rng.random(len(at)) * (hi - lo) for _ in range(5)]
    together = check_points(prog, np.array(points), np.array(readings), owners=True)
    assert [c.holds for c in together] == [True] * 3 + [False] * 5
    for c, p, r in zip(together, points, readings, strict=True):
        alone = check_point(prog, p, r, owners=True)
        assert c.holds == alone.holds and c.in_domain == alone.in_domain
        for field in ("slots", "ok", "computed", "owner"):
            assert np.array_equal(getattr(c, field), getattr(alone, field)), field
        width = alone.hi - alone.lo
        for field in ("lo", "hi"):  # the rounding differs by ulps, a small share of a width
            assert np.all(np.abs(getattr(c, field) - getattr(alone, field)) <= 0.5 * width)
        assert np.allclose(c.excess, alone.excess, rtol=1e-6, atol=1e-12)


@pytest.mark.slow
def test_test_a_inner_reaches_the_outer_box(solved_a):
    """Within 1.05 of the result; and the same inner intervals on a second run, though the
    ends' LPs and checks run in threads (a wave's points count in order, not as they come)."""
    prog, sol = solved_a
    inner = inner_bounds(prog, sol.lo, sol.hi)
    ind = independents(prog)
    outer = sol.hi[ind] - sol.lo[ind]
    assert np.all(outer / (inner.hi - inner.lo) <= 1.05)
    again = inner_bounds(prog, sol.lo, sol.hi)
    assert np.array_equal(again.lo, inner.lo) and np.array_equal(again.hi, inner.hi)
    assert again.points == inner.points


def _pivots(monkeypatch) -> list[int]:
    """The simplex iterations of every end's LP of the inner bounds, as they run."""
    from calib_dsl.inner import lp as module

    counts: list[int] = []
    extreme = module.Solver.extreme

    def counted(self, *args):
        y = extreme(self, *args)
        counts.append(self.h.getInfo().simplex_iteration_count)
        return y

    monkeypatch.setattr(module.Solver, "extreme", counted)
    return counts


@pytest.mark.slow
def test_the_solves_bases_start_the_inner_lps(monkeypatch, solved_a):
    """From the solve's final basis of each end, the inner bounds' LPs take under half the
    pivots (Test A: 670 against 4423) and reach the same inner intervals."""
    prog, sol = solved_a
    assert sol.starts is not None and len(sol.starts.ends) >= 28  # both ends of 14 unknowns
    counts = _pivots(monkeypatch)
    cold = inner_bounds(prog, sol.lo, sol.hi)
    cold_pivots = sum(counts)
    counts.clear()
    warm = inner_bounds(prog, sol.lo, sol.hi, sol.starts)
    assert sum(counts) < 0.5 * cold_pivots
    width = sol.hi[independents(prog)] - sol.lo[independents(prog)]
    assert np.all(np.abs(warm.lo - cold.lo) <= 1e-3 * width)
    assert np.all(np.abs(warm.hi - cold.hi) <= 1e-3 * width)


@pytest.mark.slow
def test_a_start_that_leads_nowhere_costs_only_pivots(monkeypatch, solved_a):
    """Every row's and column's status garbled (a basis with no meaning for these LPs): the
    same inner intervals as with no start at all."""
    from dataclasses import replace

    from calib_dsl.inner.starts import EndBasis

    prog, sol = solved_a
    assert sol.starts is not None
    rng = np.random.default_rng(2)

    def garbled(b: EndBasis) -> EndBasis:
        return replace(b, row_status=rng.integers(0, 3, len(b.row_status)).astype(np.int8),
                       unknown_status=np.full(len(b.unknown_status), 1, np.int8),
                       cell_status=rng.integers(0, 3, len(b.cell_status)).astype(np.int8))

    bad = replace(sol.starts, ends={k: garbled(b) for k, b in sol.starts.ends.items()})
    cold = inner_bounds(prog, sol.lo, sol.hi)
    warm = inner_bounds(prog, sol.lo, sol.hi, bad)
    width = sol.hi[independents(prog)] - sol.lo[independents(prog)]
    assert np.all(np.abs(warm.lo - cold.lo) <= 1e-3 * width)
    assert np.all(np.abs(warm.hi - cold.hi) <= 1e-3 * width)


@pytest.mark.slow
def test_no_optimum_at_the_middle_falls_back_to_the_fit(monkeypatch, solved_a):
    """Where the model linearized at the box's middle gives no LP optimum at all (a wide
    box's), the ends are sought again over the model linearized at the Chebyshev fit: Test A
    still within 1.05 of its result."""
    from calib_dsl.inner import lp as inner_lp

    prog, sol = solved_a
    ind = independents(prog)
    middle = 0.5 * (sol.lo[ind] + sol.hi[ind])
    extreme = inner_lp.Solver.extreme

    def none_at_the_middle(self, *args):
        if np.allclose(self.model.centre, middle, rtol=0, atol=1e-12):
            return None
        return extreme(self, *args)

    monkeypatch.setattr(inner_lp.Solver, "extreme", none_at_the_middle)
    inner = inner_bounds(prog, sol.lo, sol.hi, sol.starts)
    assert inner.consistent
    assert np.all((sol.hi[ind] - sol.lo[ind]) / (inner.hi - inner.lo) <= 1.05)


@pytest.mark.slow
def test_33_parameters_reach_their_inner_bounds():
    """rx90_recalibrate.cal on its shipped data: every unknown within 1.05 of its certified
    inner interval (1.0146 at worst; 1.087 before the fine rounds that keep the readings'
    errors as LP columns), and the inner interval inside the result. The LPs start from the
    solve's bases, as `calibc solve` does: one of them leaves the simplex stuck (alpha4's
    upper end, 1.43 if it were not solved again from HiGHS's own start)."""
    prog = load(ROOT / "models" / "rx90_recalibrate.cal")
    sol = solve(prog)
    inner = inner_bounds(prog, sol.lo, sol.hi, sol.starts)
    ind = independents(prog)
    assert np.all(sol.lo[ind] <= inner.lo) and np.all(inner.hi <= sol.hi[ind])
    assert np.all((sol.hi[ind] - sol.lo[ind]) / (inner.hi - inner.lo) <= 1.05)


def test_no_certified_point_says_so(tmp_path):
    """Two computed sides equal: a point cannot prove it, so nothing is claimed."""
    model = tmp_path / "m.cal"
    model.write_text("var x in [0, 2];\nvar y in [0, 2];\nx * x == y + y;\n")
    prog = load(model)
    sol = solve(prog)
    inner = inner_bounds(prog, sol.lo, sol.hi)
    assert not inner.consistent and np.all(np.isnan(inner.lo))


# -- the command line ---------------------------------------------------------------------
def _solve(tmp_path: Path, *args: str, model: Path = ROOT / "models" / "rx90_lengths.cal"):
    from click.testing import CliRunner

    out = tmp_path / "r.json"
    res = CliRunner().invoke(main, ["solve", str(model), "--no-identify", "--json", str(out),
                                    *args])
    return res, json.loads(out.read_text())


def _line(tmp_path: Path) -> Path:
    """A line fit on six points (what the command does with its inner bounds does not
    depend on its size; Test A runs it in test_cli_reports_inner_bounds_inside_the_result)."""
    cells = [(x, 0.5 * x - 1 + 0.1 * (-1) ** x) for x in range(6)]
    (tmp_path / "d.csv").write_text("x,y\n" + "\n".join(f"{x},{y!r}" for x, y in cells) + "\n")
    (tmp_path / "line.cal").write_text(LINE)
    return tmp_path / "line.cal"


@pytest.mark.slow
def test_cli_reports_inner_bounds_inside_the_result(tmp_path):
    res, data = _solve(tmp_path)
    assert res.exit_code == 0, res.output
    assert "certified inner" in res.stdout and "outer/inner" in res.stdout
    t = data["tightness"]
    assert t["consistent"] and t["certified"] == t["unknowns"] == 33
    assert 1.0 <= t["worst_ratio"] <= 1.05
    for p in data["parameters"].values():
        (lo, hi), (a, b) = p["result"], p["inner"]
        assert lo <= a <= b <= hi
    # what is printed stays inside what is proven
    line = next(x for x in res.stdout.splitlines() if x.startswith("r0 "))
    a_text, b_text = line.split("[")[3].split("]")[0].split(", ")
    a, b = data["parameters"]["r0"]["inner"]
    assert a <= float(a_text) <= float(b_text) <= b


def test_cli_no_inner(tmp_path):
    res, data = _solve(tmp_path, "--no-inner", model=_line(tmp_path))
    assert res.exit_code == 0, res.output
    assert "tightness" not in data and "inner" not in data["parameters"]["a"]
    assert "certified inner" not in res.stdout


def test_cli_hc4_skips_inner_bounds_unless_asked(tmp_path):
    line = _line(tmp_path)
    res, data = _solve(tmp_path, "--strategy", "hc4", model=line)
    assert res.exit_code == 0, res.output
    assert "tightness" not in data and "certified inner" not in res.stdout
    assert "inner bounds: not computed by default after --strategy hc4" in res.stdout
    res, data = _solve(tmp_path, "--strategy", "hc4", "--inner", model=line)
    assert res.exit_code == 0, res.output
    assert data["tightness"]["consistent"] and data["tightness"]["certified"] == 2
    for p in data["parameters"].values():
        (lo, hi), (a, b) = p["result"], p["inner"]
        assert lo <= a <= b <= hi


# -- rows between two computed values: existence by the intermediate value theorem ----------
CIRCLE = """param cx in [-10, 10]; param cy in [-10, 10]; param radius in [0, 10];
table m = "c.csv" { x, y : +- 1e-3; }
for k in 1..rows(m) { sqr(m.x[k] - cx) + sqr(m.y[k] - cy) == sqr(radius); }
"""


def _square_range(lo: Fraction, hi: Fraction, c: Fraction) -> tuple[Fraction, Fraction]:
    """The exact range of (x - c)^2 over [lo, hi]."""
    ends = ((lo - c) ** 2, (hi - c) ** 2)
    return (Fraction(0) if lo <= c <= hi else min(ends)), max(ends)


def _circle_row_holds(point: np.ndarray, x: str, y: str, e: Fraction = Fraction(1, 1000)
                      ) -> bool:
    """Some x', y' within e of the cells (as written) put (cx, cy, radius) on the row's
    circle: the exact range of the row's difference over that box holds 0."""
    cx, cy, r = (Fraction(v) for v in point)
    (ax, bx), (ay, by) = (_square_range(Fraction(v) - e, Fraction(v) + e, c)
                          for v, c in ((x, cx), (y, cy)))
    return ax + ay <= r * r <= bx + by


@pytest.mark.slow
@settings(max_examples=25, deadline=None)
@given(st.floats(-2, 2), st.floats(-2, 2), st.floats(1, 4), st.floats(0, 6.28),
       st.lists(st.tuples(st.floats(-0.3, 0.3), st.floats(-9e-4, 9e-4), st.floats(-9e-4, 9e-4)),
                min_size=4, max_size=8))
def test_circle_witnesses_hold_exactly(tmp_path_factory, cx, cy, r, turn, draws):
    """Points spread round a circle (the n-th at angle 2 pi n / N, moved a little), each
    coordinate off by less than its bound: the truth fits, so a point is proven."""
    tmp = tmp_path_factory.mktemp("circle")
    angles = [turn + 2 * math.pi * (n + dt) / len(draws) for n, (dt, _, _) in enumerate(draws)]
    cells = [(repr(cx + r * math.cos(t) + dx), repr(cy + r * math.sin(t) + dy))
             for t, (_, dx, dy) in zip(angles, draws, strict=True)]
    (tmp / "c.csv").write_text("x,y\n" + "\n".join(f"{x},{y}" for x, y in cells) + "\n")
    (tmp / "circle.cal").write_text(CIRCLE)
    prog = load(tmp / "circle.cal")
    sol = solve(prog)
    assert sol.status == "contracted"
    inner = inner_bounds(prog, sol.lo, sol.hi)
    assert inner.consistent  # the truth fits: a point near it is found and proven
    ind = independents(prog)
    for w in inner.witnesses:
        assert all(_circle_row_holds(w.point, x, y) for x, y in cells)
        assert np.all(sol.lo[ind] <= w.point) and np.all(w.point <= sol.hi[ind])


@pytest.mark.parametrize("tall", [False, True])
def test_ends_short_of_their_lp_optimum_are_sought_again(tmp_path, tall):
    """Five points round a circle, each coordinate off by up to 0.04 against a bound of 0.05:
    over the model linearized at the centre the corrections pull the ends well in; sought
    again from their own points they reach further (one inner interval 1.75 times as wide
    here), and every point still holds exactly. Likewise where the LPs generate their rows
    (`tall`: more rows than rows_at_once), the ends' LPs then starting from the rows the
    first ones held."""
    from dataclasses import replace

    from calib_dsl.settings import Settings

    rng = np.random.default_rng(1)
    angles = 0.3 + 2 * np.pi * np.arange(5) / 5
    cells = [(repr(float(2 + 3 * np.cos(t) + rng.uniform(-0.04, 0.04))),
              repr(float(-1 + 3 * np.sin(t) + rng.uniform(-0.04, 0.04)))) for t in angles]
    (tmp_path / "c.csv").write_text("x,y\n" + "\n".join(f"{x},{y}" for x, y in cells) + "\n")
    (tmp_path / "circle.cal").write_text(CIRCLE.replace("+- 1e-3", "+- 0.05"))
    prog = load(tmp_path / "circle.cal")
    sol = solve(prog)
    base = Settings()
    if tall:  # (ten rows: an LP of two rows at once generates the others)
        base = replace(base, lp=replace(base.lp, rows_at_once=2))
    never = replace(base, inner=replace(base.inner, refine=np.inf))  # no end sought again
    first = inner_bounds(prog, sol.lo, sol.hi, settings=never)
    inner = inner_bounds(prog, sol.lo, sol.hi, settings=base)
    assert np.all(inner.lo <= first.lo) and np.all(first.hi <= inner.hi)
    gain = (inner.hi - inner.lo) / (first.hi - first.lo)
    assert np.max(gain) > 1.3
    ind = independents(prog)
    for w in inner.witnesses:
        assert all(_circle_row_holds(w.point, x, y, Fraction(1, 20)) for x, y in cells)
        assert np.all(sol.lo[ind] <= w.point) and np.all(w.point <= sol.hi[ind])


def test_a_point_off_the_circles_is_not_proven(tmp_path):
    from calib_dsl.analysis.existence import prove_point

    (tmp_path / "c.csv").write_text("x,y\n3,0\n0,3\n-3,0\n0,-3\n")
    (tmp_path / "circle.cal").write_text(CIRCLE)
    prog = load(tmp_path / "circle.cal")
    assert prove_point(prog, np.array([0.0, 0.0, 3.0]))
    assert prove_point(prog, np.array([0.0, 0.0, 3.0009]))
    assert not prove_point(prog, np.array([0.0, 0.0, 3.0011]))  # 1.1e-3 off every cell
    assert not _circle_row_holds(np.array([0.0, 0.0, 3.0011]), "3", "0")


def test_a_failure_of_the_inner_bounds_keeps_the_result(tmp_path, monkeypatch):
    import calib_dsl.sections as sections

    def fails(*args, **kwargs):
        raise ValueError("no centre")

    monkeypatch.setattr(sections, "inner_bounds", fails)
    res, data = _solve(tmp_path, model=_line(tmp_path))
    assert res.exit_code == 0, res.output
    assert "inner bounds: not computed (ValueError: no centre)" in res.stdout
    assert data["status"] == "contracted" and "tightness" not in data


# -- one-sided rows (inequalities): the witnesses satisfy them exactly, the ends reach the hull
coef = st.floats(-3, 3, allow_nan=False, width=32)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(coef, coef, st.floats(0.5, 4, width=32)), min_size=3, max_size=7))
def test_inequality_witnesses_hold_exactly_and_reach_the_hull(tmp_path_factory, rows):
    """Half-planes a x + b y <= c (c > 0: the origin inside) in the box [-5, 5]^2: every
    witness satisfies each in exact rationals, and the inner ends reach the LP's hull."""
    lines = [f"{float(a)!r} * x + {float(b)!r} * y <= {float(c)!r};" for a, b, c in rows]
    model = tmp_path_factory.mktemp("ineq") / "h.cal"
    model.write_text("var x in [-5, 5];\nvar y in [-5, 5];\n" + "\n".join(lines) + "\n")
    prog = load(model)
    sol = solve(prog)
    inner = inner_bounds(prog, sol.lo, sol.hi)
    assert inner.consistent  # the origin is a solution
    for w in inner.witnesses:
        fx, fy = (Fraction(v) for v in w.point)
        assert all(Fraction(float(a)) * fx + Fraction(float(b)) * fy <= Fraction(float(c))
                   for a, b, c in rows)
    A = np.array([[float(a), float(b)] for a, b, _ in rows])
    rhs = np.array([float(c) for _, _, c in rows])
    for k in range(2):
        ends = []
        for sign in (1.0, -1.0):
            cost = np.zeros(2)
            cost[k] = -sign
            res = linprog(cost, A_ub=A, b_ub=rhs, bounds=[(-5, 5)] * 2, method="highs")
            ends.append(sign * -res.fun)
        hull = ends[0] - ends[1]
        assert inner.hi[k] - inner.lo[k] >= hull * (1 - 1e-3)


@pytest.mark.slow
def test_the_inner_bounds_of_test_a_do_not_import_scipy_optimize():
    """Importing scipy.optimize costs 0.3-0.4 s, most of the inner bounds' time on Test A: the
    Chebyshev fit that finds their centre calls HiGHS itself."""
    import subprocess
    import sys

    code = ("import sys; from calib_dsl.pipeline import SolveRequest, solve_report; "
            f"r = solve_report(SolveRequest({str(ROOT / 'models' / 'rx90_lengths.cal')!r})); "
            "assert r.extra.inner is not None and r.extra.inner.consistent, 'no inner bounds'; "
            "print('scipy.optimize' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "False"


@settings(max_examples=2, deadline=None,  # 6 in bench/checks/test_soundness_full.py
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(**robot_draws(st.integers(6, 14)), refine=st.sampled_from([1e-4, 1e-2]),
       at_once=st.sampled_from([3, 10, 2000]))
def test_ends_sought_again_are_certified_on_random_robots(tmp_path_factory, seed, joints, rows,
                                                          formulation, refine, at_once):
    """On simulated robots, whether the LPs hold every row or generate them (at_once), and
    however many ends are sought again (refine), every point the inner bounds return passes
    certify_point's own check, lies in the solve's box, and each inner interval lies in it."""
    from dataclasses import replace

    from calib_dsl.analysis.existence import prove_point
    from calib_dsl.settings import Settings
    from calib_dsl.strategy.tight import solve_tight

    prog = random_robot(tmp_path_factory.mktemp("robot"), seed, joints, rows, formulation).prog
    sol = solve_tight(prog, combinations=False)
    assert sol.status == "contracted"
    s = Settings()
    s = replace(s, lp=replace(s.lp, rows_at_once=at_once), inner=replace(s.inner, refine=refine))
    inner = inner_bounds(prog, sol.lo, sol.hi, settings=s)
    ind = independents(prog)
    assert inner.consistent
    for w in inner.witnesses:
        assert prove_point(prog, w.point, w.readings)
        assert np.all(sol.lo[ind] <= w.point) and np.all(w.point <= sol.hi[ind])
    ok = np.isfinite(inner.lo)
    assert np.all(sol.lo[ind][ok] <= inner.lo[ok]) and np.all(inner.hi[ok] <= sol.hi[ind][ok])
