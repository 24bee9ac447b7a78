"""Unknowns along identifiable combinations (reparametrize.py): an exact change of unknowns,
and the tight strategy on it."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from strategy.test_tight import (
    arm_solved_twice,  # the sibling test module: an arm with parallel axes
)

from calib_dsl import sections
from calib_dsl.compile.group import compile_model
from calib_dsl.elaborate.elaborator import elaborate
from calib_dsl.propagate.fixpoint import propagate
from calib_dsl.relax.layout import independents
from calib_dsl.report.extras import Extras
from calib_dsl.report.text import render_summary
from calib_dsl.settings import Settings
from calib_dsl.strategy.reparametrize import _echelon, _sum_enclosure, along_combinations, back
from calib_dsl.strategy.tight import solve_tight

SUM_MODEL = """
param a in [0, 1] true 0.1;
param b in [0, 1] true 0.2;
param c in [0, 1] true 0.25;
param e in [0, 1] true 0.2;
table m = "d.csv" { x : +- 0; y : +- 1e-6; }
for k in 1..rows(m) { a + b + 2 * c * m.x[k] + e * sqr(m.x[k]) == m.y[k]; }
"""


@pytest.fixture
def sum_model(tmp_path: Path):
    """a and b only ever act through a + b (= 0.3); c and e are identifiable."""
    xs = np.linspace(-1, 1, 7)
    rows = "".join(f"{x!r},{0.3 + 0.5 * x + 0.2 * x * x!r}\n" for x in xs.tolist())
    (tmp_path / "d.csv").write_text("x,y\n" + rows)
    (tmp_path / "m.cal").write_text(SUM_MODEL)
    return compile_model(elaborate(tmp_path / "m.cal"))


def _pinned(prog, values: dict[str, float]):
    """The program's box with these unknowns pinned to (a float interval around) a value."""
    lo, hi = prog.slots.lo.copy(), prog.slots.hi.copy()
    for name, v in values.items():
        s = prog.slots.names.index(name)
        lo[s], hi[s] = np.nextafter(v, -np.inf), np.nextafter(v, np.inf)
    return lo, hi


def test_the_rewritten_program(sum_model) -> None:
    rep = along_combinations(sum_model)
    assert rep is not None and len(rep.combinations) == 1
    text, slot, members, coef = rep.combinations[0]
    new = rep.prog
    assert text == "a + b" and new.slots.names[slot] == "a + b"
    assert list(coef) == [1.0, 1.0]  # snapped: the SVD gives 1 to a few ulps
    # the old slots first, unchanged; one of a, b is computed now (the other left free),
    # a + b is an unknown
    assert rep.old_slots == len(sum_model.slots.names)
    assert new.slots.names[: rep.old_slots] == sum_model.slots.names
    a, b = (sum_model.slots.names.index(n) for n in "ab")
    (pivot,) = [s for s in (a, b) if new.slots.kinds[s] == "temp"]
    assert rep.free == [a + b - pivot]
    assert pivot not in independents(new) and slot in independents(new)
    assert (new.slots.lo[slot], new.slots.hi[slot]) == (0.0, 2.0)
    assert (new.slots.lo[pivot], new.slots.hi[pivot]) == (0.0, 1.0)  # its own domain stays
    assert new.true_values["a + b"] == pytest.approx(0.3)
    assert len(new.primitives) == len(sum_model.primitives) + 1
    assert new.groups[0].op == "sub" and new.groups[0].level < 0  # before everything else
    lo, hi = back(rep, new.slots.lo, new.slots.hi)
    assert len(lo) == rep.old_slots


def test_the_same_solutions(sum_model) -> None:
    """A point moved along a - b (invisible to the data) is a solution of both programs; one
    moved along c is a solution of neither."""
    new = along_combinations(sum_model).prog
    for a, b, c, ok in ((0.1, 0.2, 0.25, True), (0.25, 0.05, 0.25, True),
                        (0.0, 0.3, 0.25, True), (0.1, 0.2, 0.26, False)):
        old = propagate(sum_model, tol=0, lo=_pinned(sum_model, {"a": a, "b": b, "c": c,
                                                                  "e": 0.2})[0],
                        hi=_pinned(sum_model, {"a": a, "b": b, "c": c, "e": 0.2})[1])
        box = _pinned(new, {"a + b": a + b, "b": b, "c": c, "e": 0.2})
        res = propagate(new, tol=0, lo=box[0], hi=box[1])
        assert (old.status == "contracted") == ok and (res.status == "contracted") == ok
        if ok:
            s = new.slots.names.index("a")
            assert res.lo[s] <= a <= res.hi[s]
            assert old.lo[s] <= a <= old.hi[s]


def test_solve_reports_the_combination(sum_model) -> None:
    res = solve_tight(sum_model)
    assert len(res.lo) == len(sum_model.slots.names)
    ((text, lo, hi),) = res.combinations
    assert text == "a + b" and lo <= 0.3 <= hi and hi - lo < 1e-4
    extra = Extras()
    sections.identify(extra, sum_model, res, use_lp=True)
    ((shown, a, b),) = extra.combinations  # the solve's bounds, intersected with the box's
    assert shown == "a + b" and lo <= a <= 0.3 <= b <= hi
    assert "guaranteed: a + b in [" in render_summary(sum_model, res, "tight", extra)


def test_nothing_to_change_where_all_is_identifiable(tmp_path: Path) -> None:
    xs = np.linspace(-1, 1, 7)
    rows = "".join(f"{x!r},{0.3 + 0.5 * x!r}\n" for x in xs.tolist())
    (tmp_path / "d.csv").write_text("x,y\n" + rows)
    (tmp_path / "m.cal").write_text(
        'param a in [0, 1] true 0.3;\nparam c in [0, 1] true 0.25;\n'
        'table m = "d.csv" { x : +- 0; y : +- 1e-6; }\n'
        'for k in 1..rows(m) { a + 2 * c * m.x[k] == m.y[k]; }\n')
    prog = compile_model(elaborate(tmp_path / "m.cal"))
    assert along_combinations(prog) is None
    assert solve_tight(prog).combinations == ()


def test_no_change_on_a_program_too_large_to_analyse(sum_model, monkeypatch) -> None:
    """Above settings.routine_max_primitives the analysis would cost more than it saves:
    the program is solved as it is (the same box as asking for no change)."""
    from dataclasses import replace

    from calib_dsl.settings import DEFAULT

    small = replace(DEFAULT, routine_max_primitives=len(sum_model.primitives) - 1)
    assert along_combinations(sum_model, small) is None
    res = solve_tight(sum_model, settings=small)
    plain = solve_tight(sum_model, combinations=False)
    assert res.combinations == ()
    assert np.array_equal(res.lo, plain.lo) and np.array_equal(res.hi, plain.hi)


finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)


@pytest.mark.slow
@settings(max_examples=2000, deadline=None)
@given(data=st.data(), n=st.integers(1, 5))
def test_sum_enclosure_holds_every_sum(data, n) -> None:
    """[sum c_i x_i] over the box, against the exact (rational) extremes: the products and
    sums round outward, and a coefficient of +-1 (exact) as well as any other."""
    coef = np.array(data.draw(st.lists(st.one_of(st.sampled_from([1.0, -1.0]), finite),
                                       min_size=n, max_size=n)))
    lo = np.array(data.draw(st.lists(finite, min_size=n, max_size=n)))
    width = np.array(data.draw(st.lists(st.floats(0, 1e6), min_size=n, max_size=n)))
    hi = lo + width
    a, b = _sum_enclosure(coef, lo, hi)
    exact = [(Fraction(c) * Fraction(x), Fraction(c) * Fraction(y))
             for c, x, y in zip(coef.tolist(), lo.tolist(), hi.tolist(), strict=True)]
    assert Fraction(a) <= sum(min(p) for p in exact)
    assert sum(max(p) for p in exact) <= Fraction(b)


@settings(max_examples=500, deadline=None)
@given(data=st.data(), k=st.integers(1, 3), extra=st.integers(1, 3))
def test_echelon_spans_the_same_combinations(data, k, extra) -> None:
    m = k + extra
    rows = np.array(data.draw(st.lists(st.lists(st.floats(-10, 10), min_size=m, max_size=m),
                                       min_size=k, max_size=k)))
    if np.linalg.matrix_rank(rows, tol=1e-6) < k or np.linalg.cond(rows) > 1e6:
        return
    out = _echelon(rows, Settings().snap)
    assert len(out) == k
    pivots = [p for p, _ in out]
    assert len(set(pivots)) == k
    mat = np.array([c for _, c in out])
    for r, p in enumerate(pivots):
        assert mat[r, p] == 1.0 and all(mat[q, p] == 0.0 for q in range(k) if q != r)
    # the same row space: stacking adds no rank
    assert np.linalg.matrix_rank(np.vstack([rows, mat]), tol=1e-6) == k


@pytest.mark.slow
@settings(max_examples=5, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31 - 1))
def test_parallel_axes_solved_along_their_sum(tmp_path_factory, seed) -> None:
    """r2 and r3 of +-0.05 m on parallel axes: the solve in r2 + r3 and r3 holds the truth and
    the true r2 + r3, and its box of the seven others is narrower than the solve in r2 and r3
    gives (geometric mean 0.72-0.90 of it over 6 seeds; no gain would be 1)."""
    _, p_true, ind, names, plain, res = arm_solved_twice(
        tmp_path_factory.mktemp("par"), seed, {"split": False, "combinations": False}, {})
    assert plain.status == res.status == "contracted"
    assert np.all(res.lo[ind] <= p_true) and np.all(p_true <= res.hi[ind])
    # (alpha3 is 0 at the middle of its domain: the analysis always finds r2 + r3)
    ((text, a, b),) = res.combinations
    assert text == "r2 + r3"
    assert a <= p_true[names.index("r2")] + p_true[names.index("r3")] <= b
    others = [k for k, n in enumerate(names) if n not in ("r2", "r3")]
    ratio = (res.hi[ind] - res.lo[ind]) / (plain.hi[ind] - plain.lo[ind])
    assert np.exp(np.mean(np.log(ratio[others]))) < 0.97, dict(zip(names, ratio, strict=True))
