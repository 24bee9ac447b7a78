"""solve --outliers K: the enclosure holds every parameter vector that satisfies all data rows
but at most K (checked against the exact hull of that set on a line fit), and on the RX90's
Test A a moved tool coordinate is found and costs no tightness."""

from __future__ import annotations

import itertools
import json
import math
import tempfile
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.optimize import linprog

from calib_dsl.cli import main
from calib_dsl.outliers import solve as outliers
from calib_dsl.outliers.solve import groups
from calib_dsl.pipeline import SolveRequest, load, solve_report
from calib_dsl.propagate.diagnose import Emptied
from calib_dsl.settings import OutlierSettings
from calib_dsl.strategy.contractor import Work
from calib_dsl.strategy.solution import Solution

ROOT = Path(__file__).resolve().parents[2]
RX90 = ROOT / "models" / "rx90_lengths.cal"
LINE = """param a in [-2, 2]; param b in [-2, 2];
table m = "d.csv" { x : +- 1e-12; v : +- 0.05; }
for k in 1..rows(m) { a * m.x[k] + b == m.v[k]; }
"""
E = 0.05


def _hull(x: np.ndarray, v: np.ndarray, k: int) -> np.ndarray | None:
    """The exact [min, max] of a and b over the vectors in [-2, 2]^2 with |a x + b - v| <= E
    on all rows but at most k (every k-subset left out in turn: an LP each), or None."""
    hull = None
    for out in itertools.combinations(range(len(x)), k):
        keep = np.setdiff1d(np.arange(len(x)), out)
        A = np.concatenate([np.stack([x[keep], np.ones(len(keep))], 1),
                            -np.stack([x[keep], np.ones(len(keep))], 1)])
        b = np.concatenate([v[keep] + E, E - v[keep]])
        ends = []
        for c in ([1, 0], [-1, 0], [0, 1], [0, -1]):
            r = linprog(c, A_ub=A, b_ub=b, bounds=[(-2, 2)] * 2, method="highs")
            if r.status != 0:
                break
            ends.append(r.fun)
        if len(ends) == 4:
            here = np.array([[ends[0], -ends[1]], [ends[2], -ends[3]]])
            hull = here if hull is None else np.stack(
                [np.minimum(hull[:, 0], here[:, 0]), np.maximum(hull[:, 1], here[:, 1])], 1)
    return hull


FITS = dict(seed=st.integers(0, 2**32 - 1), k=st.sampled_from([1, 2]), n=st.integers(4, 7))


@pytest.mark.slow
@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(**FITS)
def test_the_enclosure_holds_the_exact_hull(seed, k, n):
    """8 line fits here, 32 more in bench/checks/test_outlier_test_a.py."""
    enclosure_holds_the_exact_hull(seed, k, n)


def enclosure_holds_the_exact_hull(seed: int, k: int, n: int) -> None:
    rng = np.random.default_rng(seed)
    x = rng.uniform(0, 3, n).round(3)
    v = (rng.uniform(-0.5, 0.5) * x + rng.uniform(-0.5, 0.5) + rng.uniform(-E, E, n)).round(3)
    bad = rng.choice(n, rng.integers(0, 3), replace=False)
    v[bad] += rng.choice([-1, 1], len(bad)) * rng.uniform(0.02, 1.0, len(bad))
    v = v.round(3)
    with tempfile.TemporaryDirectory() as tmp:
        rows = zip(x.tolist(), v.tolist(), strict=True)
        (Path(tmp) / "d.csv").write_text("x,v\n" + "".join(f"{a!r},{b!r}\n" for a, b in rows))
        (Path(tmp) / "line.cal").write_text(LINE)
        run = solve_report(SolveRequest(Path(tmp) / "line.cal", outliers=k, identify=False))
    hull = _hull(x, v, k)
    if hull is None:
        return  # S_K is empty: any answer holds it
    assert run.res.status == "contracted"
    names = run.prog.slots.names
    for row, name in enumerate(("a", "b")):
        i = names.index(name)
        slack = 1e-9 * (1 + np.abs(hull[row]))
        assert run.res.lo[i] <= hull[row, 0] + slack[0]
        assert run.res.hi[i] >= hull[row, 1] - slack[1]
    assert run.outliers is not None
    assert len(run.outliers.certain) <= k
    for r in run.outliers.certain:  # fails for every vector of S_K
        assert not _satisfiable_with(x, v, k, r.row - 1), r
    listed = {r.row for r in run.outliers.certain + run.outliers.possible}
    for r in range(n):  # a row neither listed holds for every vector of S_K
        assert r + 1 in listed or not _fails_somewhere(x, v, k, r), r + 1


def _fails_somewhere(x: np.ndarray, v: np.ndarray, k: int, row: int) -> bool:
    """Whether a vector fails row `row` and satisfies all the other rows but at most k - 1."""
    others = [i for i in range(len(x)) if i != row]
    for out in itertools.combinations(others, min(k - 1, len(others))):
        keep = np.setdiff1d(others, out)
        A = np.concatenate([np.stack([x[keep], np.ones(len(keep))], 1),
                            -np.stack([x[keep], np.ones(len(keep))], 1)])
        b = np.concatenate([v[keep] + E, E - v[keep]])
        for side in (1.0, -1.0):  # beyond the row's bound, above or below
            A_r = -side * np.array([[x[row], 1.0]])
            b_r = np.array([-side * v[row] - E - 1e-9])
            r = linprog([0, 0], A_ub=np.concatenate([A, A_r]), b_ub=np.concatenate([b, b_r]),
                        bounds=[(-2, 2)] * 2, method="highs")
            if r.status == 0:
                return True
    return False


def _satisfiable_with(x: np.ndarray, v: np.ndarray, k: int, row: int) -> bool:
    """Whether a vector satisfies row `row` and all the other rows but at most k."""
    others = [i for i in range(len(x)) if i != row]
    for out in itertools.combinations(others, min(k, len(others))):
        keep = np.setdiff1d(np.arange(len(x)), out)
        if _hull(x[keep], v[keep], 0) is not None:
            return True
    return False


def test_the_command_line_writes_the_outliers(tmp_path):
    (tmp_path / "d.csv").write_text("x,v\n0,0.1\n1,0.3\n2,0.5\n3,2.9\n4,0.9\n")
    (tmp_path / "line.cal").write_text(LINE)
    res = CliRunner().invoke(main, ["solve", str(tmp_path / "line.cal"), "--outliers", "1",
                                    "--json", "-", "-q"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.output)
    assert data["outliers"]["certain"] == [4]
    assert data["outliers"]["possible"] == []
    assert data["outliers"]["rows"][0]["line"] == 5
    assert "tightness" not in data  # no inner bounds: they would assume every row holds


def test_two_certain_outliers_with_one_allowed_are_inconsistent(tmp_path):
    v = [0.2 * x + 0.1 for x in range(8)]
    v[2], v[5] = 1.5, 0.0  # rows 3 and 6 are off
    (tmp_path / "d.csv").write_text("x,v\n" + "".join(f"{x},{y:.3f}\n"
                                                      for x, y in enumerate(v)))
    (tmp_path / "line.cal").write_text(LINE)
    res = CliRunner().invoke(main, ["solve", str(tmp_path / "line.cal"), "--outliers", "1",
                                    "-q"])
    assert res.exit_code == 1, res.output
    assert "status: infeasible" in res.output
    assert "d.csv:4 (row 3)" in res.output and "d.csv:7 (row 6)" in res.output
    res = CliRunner().invoke(main, ["solve", str(tmp_path / "line.cal"), "--outliers", "2",
                                    "--json", "-", "-q"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.output)["outliers"]["certain"] == [3, 6]


def test_a_row_passed_over_is_proven_once_another_row_is(tmp_path):
    """Row 9 has the largest residual but fits one of the thirds of the other rows (one holds
    row 4, also off); once row 4 is proven, row 9 is proven against halves."""
    x = np.arange(9.0)
    v = np.array([0.122, 0.282, 0.547, 0.561, 0.896, 1.071, 1.25, 1.528, 1.403])
    rows = zip(x.tolist(), v.tolist(), strict=True)
    (tmp_path / "d.csv").write_text("x,v\n" + "".join(f"{a},{b}\n" for a, b in rows))
    (tmp_path / "line.cal").write_text(LINE)
    run = solve_report(SolveRequest(tmp_path / "line.cal", outliers=2, identify=False))
    assert run.outliers is not None
    assert sorted(r.row for r in run.outliers.certain) == [4, 9]
    assert run.outliers.proven == 2  # both by the proof, before the LPs
    for r in run.outliers.certain:  # fails for every vector of S_2 (brute force)
        assert not _satisfiable_with(x, v, 2, r.row - 1)


def test_a_model_without_a_table_is_a_user_error():
    res = CliRunner().invoke(main, ["solve", str(ROOT / "models/examples/paper_cse.cal"),
                                    "--outliers", "1"])
    assert res.exit_code == 2
    assert "error:" in res.output and "no table" in res.output
    assert "Traceback" not in res.output


def test_groups_keep_the_sets_within_their_count():
    assert [groups(k, 4) for k in (1, 2, 3, 5)] == [4, 3, 4, 6]
    assert groups(1, 6) == 6 and groups(2, 6) == 4
    for k in range(1, 6):
        m = groups(k)
        assert m >= k + 1 and (m == k + 1 or math.comb(m, k) <= OutlierSettings().most_sets)


def _block_box_with(solve_set, prog, k, without, suspects):
    """block_box with `solve_set` in place of the tight solve of each set (a hypothesis test
    cannot take pytest's monkeypatch)."""
    real = outliers.solve_tight
    outliers.solve_tight = solve_set
    try:
        return outliers.block_box(prog, k, without, suspects=suspects)
    finally:
        outliers.solve_tight = real


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(n=st.integers(2, 12), k=st.integers(1, 3), data=st.data())
def test_some_set_leaves_out_any_k_rows(n, k, data):
    """Whatever k rows a vector fails, block_box solves a set of rows without them: the sets
    it solves (the rows each leaves out, as `without` is asked) cover every choice of k,
    whichever rows are suspects."""
    suspects = data.draw(st.lists(st.integers(0, n - 1), max_size=5, unique=True))
    prog = load(ROOT / "models" / "examples" / "paper_cse.cal")
    prog.slots.row_keys = [("m", r + 1) for r in range(n)]
    left_out: list[set[int]] = []

    def without(rows: list[int]):
        left_out.append(set(rows))
        return prog

    def refuted(*_a, **_k):  # every set proven inconsistent: only the sets asked matter
        return Solution("tight", prog.slots.lo, prog.slots.hi, "empty", 0.0, Work(),
                        Emptied("x", None, None))

    box = _block_box_with(refuted, prog, k, without, suspects)
    if n <= k:
        assert left_out == [] and box is not None  # every row may fail: the domains
        return
    parts = outliers.partition(list(range(n)), k, suspects)
    assert box is None and len(left_out) == math.comb(len(parts), k)
    for failed in itertools.combinations(range(n), k):
        assert any(set(failed) <= out for out in left_out), failed


def test_rows_that_exclude_each_other_are_both_possible_and_all_others_hold(tmp_path):
    """Two readings of the same point 2.4 bounds apart: either may be the outlier, so neither
    is certain. The sets that keep both out of the way are refuted, so they are the only
    rows any vector of S_1 fails (before the sets, every row stayed possible)."""
    x = list(range(9)) + [4]
    v = [0.1 * a + 0.2 for a in range(9)] + [0.0]
    v[4], v[9] = 0.6 + 0.06, 0.6 - 0.06  # rows 5 and 10
    (tmp_path / "d.csv").write_text("x,v\n" + "".join(f"{a},{b:.3f}\n" for a, b in zip(
        x, v, strict=True)))
    (tmp_path / "line.cal").write_text(LINE)
    run = solve_report(SolveRequest(tmp_path / "line.cal", outliers=1, identify=False))
    assert run.res.status == "contracted" and run.outliers is not None
    assert run.outliers.certain == []
    assert sorted(r.row for r in run.outliers.possible) == [5, 10]
    hull = _hull(np.array(x, float), np.round(v, 3), 1)
    assert hull is not None
    names = run.prog.slots.names
    for row, name in enumerate(("a", "b")):
        i = names.index(name)
        assert run.res.lo[i] <= hull[row, 0] + 1e-9 and run.res.hi[i] >= hull[row, 1] - 1e-9


@settings(max_examples=60, deadline=None)
@given(n=st.integers(5, 40), k=st.integers(1, 3), data=st.data())
def test_partition_puts_suspects_alone_and_keeps_the_sets_few(n, k, data):
    ids = list(range(n))
    suspects = data.draw(st.lists(st.integers(0, n - 1), max_size=6, unique=True))
    parts = outliers.partition(ids, k, suspects)
    assert sorted(r for g in parts for r in g) == ids  # every row in exactly one group
    m = outliers.groups(k)
    j = max(s for s in range(len(suspects) + 1)
            if s == 0 or math.comb(s + m, k) <= OutlierSettings().most_suspect_sets)
    assert parts[:j] == [frozenset([r]) for r in suspects[:j]]  # the worst first, alone
    assert len(parts) <= j + m  # the others in groups(k) groups (fewer if few rows)
    assert math.comb(len(parts), k) <= max(OutlierSettings().most_suspect_sets, math.comb(m, k))


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(n=st.integers(3, 10), k=st.integers(1, 2), data=st.data())
def test_what_the_sets_prove_holds_in_any_world(n, k, data):
    """A world of conflicts: a set of rows is consistent unless it holds all the rows of some
    conflict. Whatever the conflicts and the suspects, the rows block_box calls certain fail
    at every vector of S_k (every consistent set of all rows but at most k misses them) and
    every row some vector fails is among those it says may fail."""
    rows = st.lists(st.integers(0, n - 1), min_size=1, max_size=3, unique=True)
    conflicts = [set(c) for c in data.draw(st.lists(rows, max_size=4))]
    suspects = data.draw(st.lists(st.integers(0, n - 1), max_size=4, unique=True))
    prog = load(ROOT / "models" / "examples" / "paper_cse.cal")
    prog.slots.row_keys = [("m", r + 1) for r in range(n)]
    asked: list[set[int]] = []

    def without(out: list[int]):
        asked.append(set(range(n)) - set(out))
        return prog

    def solve_set(*_a, **_k):
        bad = any(c <= asked[-1] for c in conflicts)
        return Solution("tight", prog.slots.lo, prog.slots.hi, "empty" if bad else "fixed point",
                        0.0, Work(), Emptied("x", None, None) if bad else None)

    blocks = _block_box_with(solve_set, prog, k, without, suspects)
    # S_k, as the sets of rows its vectors fail: J, |J| <= k, whose rest is consistent
    fails = [set(j) for size in range(k + 1) for j in itertools.combinations(range(n), size)
             if not any(c <= set(range(n)) - set(j) for c in conflicts)]
    if blocks is None:
        assert fails == []
        return
    for r in blocks.certain(k):
        assert all(r in j for j in fails), (r, fails)
    assert set().union(*fails) <= blocks.may_fail()
