"""The fixed-point propagator (forward-backward sweeps) and the tight strategy: the paper's
examples, stop criteria, infeasibility diagnosis, and results that never lose a solution."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from calib_dsl.compile.group import compile_model
from calib_dsl.elaborate.elaborator import elaborate
from calib_dsl.ir.program import Program
from calib_dsl.propagate.fixpoint import propagate
from calib_dsl.strategy.tight import solve_tight

EXAMPLES = Path(__file__).resolve().parents[2] / "models" / "examples"

INF = math.inf
# The paper's propagation example: x1 = sin(x2) = x2^3 has the solutions 0 and +-(x2*, x1*).
X2_STAR = brentq(lambda x: x**3 - math.sin(x), 0.5, 1.5, xtol=1e-15)
X1_STAR = X2_STAR**3


def load(name: str, formulation: str = "matrix") -> Program:
    return compile_model(elaborate(EXAMPLES / name, formulation=formulation))


def box(prog: Program, res, name: str) -> tuple[float, float]:
    s = prog.slots
    i = s.declared[s.declared_names.index(name)]
    return float(res.lo[i]), float(res.hi[i])


def assert_encloses_closely(got: tuple[float, float], want: tuple[float, float],
                            eps: float) -> None:
    """`got` holds `want` (outward rounding only widens) and is within eps of it."""
    assert got[0] <= want[0] and want[1] <= got[1], (got, want)
    assert want[0] - got[0] <= eps and got[1] - want[1] <= eps, (got, want)


# -- the paper's Example 1 (eq. [9]-[13]): the optimal contractor of x3 = x2 - x1 ---------------

@pytest.mark.parametrize("domains, expected", [
    (((1, 2), (1, 6), (1, 3)), ((1, 2), (2, 5), (1, 3))),   # [a] -> eq. [12]
    (((4, 7), (2, 6), (1, 3)), ((4, 5), (5, 6), (1, 2))),   # [b] -> eq. [13]
])
def test_paper_example_1(compile_src, domains, expected):
    decl = "".join(f"var x{i + 1} in [{lo}, {hi}];\n" for i, (lo, hi) in enumerate(domains))
    prog = compile_src(decl + "x3 == x2 - x1;\n")
    assert [p.op for p in prog.primitives] == ["sub"]
    res = propagate(prog, tol=0.0)
    assert res.status == "contracted"
    assert res.stop == "fixed point"
    assert res.sweeps == 2  # one projection is optimal: the second sweep changes nothing
    for i, want in enumerate(expected):
        assert_encloses_closely(box(prog, res, f"x{i + 1}"), want, 1e-12)


# -- the paper's propagation example (eq. [15]-[21]) ------------------------------------------

def test_paper_propagation_first_sweeps():
    prog = load("paper_propagation.cal")
    one = propagate(prog, max_sweeps=1)
    assert (one.stop, one.sweeps) == ("max sweeps", 1)
    assert box(prog, one, "x1") == (-1.0, 1.0)  # eq. [18]-[19]: [-1, 1] x [-1, 1]
    assert_encloses_closely(box(prog, one, "x2"), (-1.0, 1.0), 1e-12)  # a cube root
    two = propagate(prog, max_sweeps=2)
    lo, hi = box(prog, two, "x1")  # eq. [20]: [-0.84, 0.85]: sin([-1, 1])
    assert_encloses_closely((lo, hi), (-math.sin(1.0), math.sin(1.0)), 1e-12)


@pytest.mark.parametrize("tol", [0.0, 1e-5])
def test_paper_propagation_reaches_the_hull_of_the_solutions(tol):
    prog = load("paper_propagation.cal")
    res = propagate(prog, tol=tol)
    assert res.status == "contracted"
    # the true solutions are inside (soundness) and the box is their hull (within 1e-3)
    for name, star in (("x1", X1_STAR), ("x2", X2_STAR)):
        lo, hi = box(prog, res, name)
        assert lo <= -star and star <= hi
        assert abs(lo + star) < 1e-3 and abs(hi - star) < 1e-3
    assert abs(X1_STAR - 0.8008) < 1e-4 and abs(X2_STAR - 0.9286) < 1e-4


def test_paper_propagation_tight_strategy():
    prog = load("paper_propagation.cal")
    res = solve_tight(prog)
    for name, star in (("x1", X1_STAR), ("x2", X2_STAR)):
        assert_encloses_closely(box(prog, res, name), (-star, star), 1e-3)


# -- stop criteria ------------------------------------------------------------------------------

def test_stop_reasons():
    prog = load("paper_propagation.cal")
    fixed = propagate(prog, tol=0.0, max_sweeps=1000)
    assert fixed.stop == "fixed point" and 10 < fixed.sweeps < 1000
    loose = propagate(prog, tol=0.5)
    assert loose.stop == "tolerance" and loose.sweeps == 2
    default = propagate(prog)
    assert default.stop == "tolerance" and default.sweeps < fixed.sweeps
    capped = propagate(prog, tol=0.0, max_sweeps=5)
    assert capped.stop == "max sweeps" and capped.sweeps == 5
    # a fixed point is a fixed point: one more sweep from it changes nothing
    again = propagate(prog, tol=0.0, lo=fixed.lo, hi=fixed.hi)
    assert again.sweeps == 1 and again.stop == "fixed point"
    assert np.array_equal(again.lo, fixed.lo) and np.array_equal(again.hi, fixed.hi)


def test_more_sweeps_give_nested_boxes():
    prog = load("paper_propagation.cal")
    prev = None
    for k in range(1, 12):
        res = propagate(prog, tol=0.0, max_sweeps=k)
        if prev is not None:
            assert np.all(res.lo >= prev.lo) and np.all(res.hi <= prev.hi)
        prev = res


def test_tolerance_is_relative_to_each_unknown():
    prog = load("planar_arm.cal")
    coarse, fine = propagate(prog, tol=1e-2), propagate(prog, tol=1e-9)
    assert coarse.sweeps < fine.sweeps
    for name in ("l1", "l2"):
        c, f = box(prog, coarse, name), box(prog, fine, name)
        assert c[0] <= f[0] and f[1] <= c[1]


def test_half_unbounded_unknown_does_not_defeat_the_tolerance(compile_src):
    prog = compile_src("var x1, x2 in [-oo, oo];\nvar w;\nx1 == sin(x2);\nx1 == x2^3;\n"
                       "w >= x2;\n")
    res = propagate(prog, tol=1e-5)
    assert res.stop == "tolerance"


# -- the box: never widened, given boxes untouched -----------------------------------------------

@pytest.mark.parametrize("name, formulation", [
    ("paper_cse.cal", "matrix"), ("paper_propagation.cal", "matrix"),
    ("circle_fit.cal", "matrix"), ("language_tour.cal", "matrix"),
    ("planar_arm.cal", "matrix"), ("planar_arm.cal", "rotation")])
@pytest.mark.parametrize("strategy", ["hc4", "tight"])
def test_never_widens_and_keeps_true_values(name, formulation, strategy):
    prog = load(name, formulation)
    lo0, hi0 = prog.slots.lo.copy(), prog.slots.hi.copy()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        res = propagate(prog) if strategy == "hc4" else solve_tight(prog)
    assert res.status == "contracted"
    assert np.all(res.lo >= lo0) and np.all(res.hi <= hi0)
    assert np.all(res.lo <= res.hi)
    assert np.array_equal(prog.slots.lo, lo0) and np.array_equal(prog.slots.hi, hi0)
    for var, true in prog.true_values.items():
        if true is not None:
            lo, hi = box(prog, res, var)
            assert lo <= true <= hi, (var, true, lo, hi)


def test_planar_arm_contracts_to_the_true_lengths():
    for formulation in ("matrix", "rotation"):
        prog = load("planar_arm.cal", formulation)
        res = propagate(prog)
        for name, true in (("l1", 1.0), ("l2", 0.5)):
            lo, hi = box(prog, res, name)
            assert lo <= true <= hi and hi - lo < 1e-3


def test_given_box_is_not_modified_and_bounds_the_result():
    prog = load("paper_propagation.cal")
    lo = np.array([-0.9, -2.0])
    hi = np.array([0.5, 0.95])
    keep = (lo.copy(), hi.copy())
    res = propagate(prog, tol=0.0, lo=lo, hi=hi)
    assert np.array_equal(lo, keep[0]) and np.array_equal(hi, keep[1])
    assert np.all(res.lo >= lo) and np.all(res.hi <= hi)
    x1, x2 = box(prog, res, "x1"), box(prog, res, "x2")
    # solutions left in the box: 0 and (-x1*, -x2*); the positive one is cut off by x1 <= 0.5
    assert x2[0] <= -X2_STAR and 0.0 <= x2[1] < X2_STAR
    assert x1[0] <= -X1_STAR


def test_empty_given_box_is_infeasible_at_once():
    prog = load("paper_propagation.cal")
    res = propagate(prog, lo=np.array([0.5, 0.0]), hi=np.array([0.4, 1.0]))
    assert (res.status, res.stop, res.sweeps) == ("infeasible", "empty", 0)
    assert res.emptied is not None and res.emptied.variable == "x1"


def test_model_without_constraints_is_a_fixed_point(compile_src):
    prog = compile_src("var x in [0, 1];\nparam p in [-oo, 2];\n")
    res = propagate(prog)
    assert (res.status, res.stop, res.sweeps) == ("contracted", "fixed point", 1)
    assert box(prog, res, "p") == (-INF, 2.0)


# -- infeasibility -------------------------------------------------------------------------------

def test_infeasible_names_the_variable_and_the_line(compile_src):
    prog = compile_src("var x in [0, 1];\nvar y in [0, 1];\nvar z in [3, 4];\n\n"
                       "z == x + y;\n")
    res = propagate(prog)
    assert (res.status, res.stop) == ("infeasible", "empty")
    e = res.emptied
    assert e.variable == "z"
    assert e.loc is not None and e.loc.line == 5 and e.loc.file.endswith("m.cal")
    assert e.primitive == "z = x + y"


def test_infeasible_sum_equal_to_a_constant(compile_src):
    prog = compile_src("var x in [0, 1];\nvar y in [0, 1];\nx + y == 3;\n")
    res = propagate(prog)
    assert res.status == "infeasible"
    assert res.emptied.loc.line == 3
    assert "x + y" in res.emptied.primitive


def test_infeasible_report_names_an_unknown_not_a_constant(compile_src):
    prog = compile_src("var x in [0, 1];\nvar y in [0, 1];\nx + y == 3;\n")
    res = propagate(prog)
    assert res.emptied.variable in ("x", "y")


def test_infeasible_deep_in_the_model(compile_src):
    prog = compile_src("var a in [0, 1];\nvar b in [-1, 1];\nvar c;\nc == exp(a) + sqr(b);\n"
                       "c <= 0.5;\n")
    res = propagate(prog)
    assert res.status == "infeasible"
    assert res.emptied.loc.line in (4, 5)
    assert res.emptied.primitive is not None


def test_infeasible_inequality(compile_src):
    prog = compile_src("var x in [0, 1];\nx >= 2;\n")
    res = propagate(prog)
    assert res.status == "infeasible"
    assert res.emptied.loc.line == 2
    assert "x - 2" in res.emptied.primitive


def test_empty_at_compile_time_is_infeasible_without_a_sweep(compile_src):
    prog = compile_src("var x in [0, 1];\nvar y;\n\nx == 3;\n")
    res = propagate(prog)
    assert (res.status, res.sweeps) == ("infeasible", 0)
    assert res.emptied.variable == "x"
    assert res.emptied.loc is not None


def test_empty_at_compile_time_names_the_constraint_line(compile_src):
    prog = compile_src("var x in [0, 1];\nvar y;\n\nx == 3;\n")
    assert propagate(prog).emptied.loc.line == 4


def test_tight_strategy_reports_infeasibility(compile_src):
    prog = compile_src("var x in [0, 1];\nvar y in [0, 1];\nvar z in [3, 4];\nz == x + y;\n")
    res = solve_tight(prog)
    assert res.status == "infeasible" and res.emptied is not None


def test_result_fields(compile_src):
    prog = compile_src("var x in [0, 4];\nvar y;\ny == sqrt(x);\n")
    res = propagate(prog, tol=0.0)
    assert res.status == "contracted" and res.emptied is None
    assert res.seconds >= 0.0 and res.stop in ("fixed point", "tolerance")
    assert res.lo.shape == res.hi.shape == prog.slots.lo.shape
    lo, hi = box(prog, res, "y")
    assert lo == 0.0 and 2.0 <= hi < 2.0 + 1e-12
