"""Decomposition: DAG + constraints -> slots and three-address primitives (CSE, unification of
`==` sides, congruence closure, inequality caps, constant folding, two-output rotations)."""

from __future__ import annotations

import math
import re
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from calib_dsl.compile.decompose import decompose
from calib_dsl.compile.group import compile_model
from calib_dsl.compile.listing import render_primitive
from calib_dsl.elaborate.elaborator import elaborate
from calib_dsl.ir.dag import Dag
from calib_dsl.ir.model import Model
from calib_dsl.ir.primitives import format_const
from calib_dsl.ir.program import Program
from calib_dsl.propagate.fixpoint import propagate

EXAMPLES = Path(__file__).resolve().parents[2] / "models" / "examples"

INF = math.inf


def ops(prog: Program) -> Counter:
    return Counter(p.op for p in prog.primitives)


def texts(prog: Program) -> list[str]:
    return [render_primitive(p, prog.slots.names) for p in prog.primitives]


def slot(prog: Program, name: str) -> int:
    s = prog.slots
    return s.declared[s.declared_names.index(name)]


# -- the paper's compilation example (eq. [22]-[25]) -------------------------------------------

def test_paper_cse_has_six_primitives_and_one_sine():
    prog = compile_model(elaborate(EXAMPLES / "paper_cse.cal"))
    assert len(prog.primitives) == 6
    assert ops(prog) == Counter({"add": 2, "cos": 1, "sin": 1, "sqr": 1, "mul": 1})
    # every primitive has one output and no slot is produced twice
    outs = [p.out for p in prog.primitives]
    assert all(len(o) == 1 for o in outs)
    assert len(set(outs)) == 6


def test_paper_cse_intermediates_are_unbounded_temporaries():
    prog = compile_model(elaborate(EXAMPLES / "paper_cse.cal"))
    s = prog.slots
    temps = [i for i, k in enumerate(s.kinds) if k == "temp"]
    assert len(temps) == 4  # i1+i2, cos, sin, sqr
    assert all(s.lo[i] == -INF and s.hi[i] == INF for i in temps)
    assert (s.lo[slot(prog, "y1")], s.hi[slot(prog, "y1")]) == (0.5, 1.0)


def test_each_primitive_keeps_the_first_constraint_reaching_it():
    prog = compile_model(elaborate(EXAMPLES / "paper_cse.cal"))
    lines = {t: p.loc.line for t, p in zip(texts(prog), prog.primitives, strict=True)}
    shared = [t for t in lines if t.endswith("= i1 + i2") or "sin(" in t]
    assert shared and all(lines[t] == 8 for t in shared)  # first reached by line 8
    assert lines[next(t for t in lines if t.startswith("y2 ="))] == 9
    assert lines[next(t for t in lines if "sqr(" in t)] == 9


def test_location_is_the_first_constraint_in_source_order(compile_src):
    prog = compile_src("var a, y, z, b;\ny == sin(a);\ncos(b) + sin(a) == z;\n")
    sin = next(p for p in prog.primitives if p.op == "sin")
    assert sin.loc.line == 2


def test_an_inequality_locates_its_difference_before_a_later_use(compile_src):
    # `a <= b` is the primitive `a - b` (line 2) before line 3 reuses it
    prog = compile_src("var a, b, z;\na <= b;\nz == a - b;\n")
    sub = next(p for p in prog.primitives if p.op == "sub")
    assert sub.loc.line == 2


# -- common sub-expressions -------------------------------------------------------------------

@pytest.mark.parametrize("op, a, b", [("+", "a + b", "b + a"), ("*", "a * b", "b * a")])
def test_commutative_operands_meet(compile_src, op, a, b):
    prog = compile_src(f"var a, b, u, v;\nu == sin({a});\nv == cos({b});\n")
    binop = "add" if op == "+" else "mul"
    assert ops(prog) == Counter({binop: 1, "sin": 1, "cos": 1})


@pytest.mark.parametrize("a, b, op", [("a - b", "b - a", "sub"), ("a / b", "b / a", "div"),
                                      ("atan2(a, b)", "atan2(b, a)", "atan2")])
def test_non_commutative_operands_stay_apart(compile_src, a, b, op):
    prog = compile_src(f"var a, b, u, v;\nu == sin({a});\nv == cos({b});\n")
    assert ops(prog)[op] == 2


def test_shared_subexpression_across_constraints(compile_src):
    prog = compile_src("var a, b, c, u, v;\nu == exp(a * b + c);\nv == log(a * b + c) + a * b;\n")
    assert ops(prog) == Counter({"mul": 1, "add": 2, "exp": 1, "log": 1})


def test_loop_generating_the_same_expression_is_one_primitive(compile_src):
    prog = compile_src("var a, b, z;\nfor k in 1..10 { z == cos(a) * b; }\n")
    assert ops(prog) == Counter({"cos": 1, "mul": 1})
    assert texts(prog)[-1].startswith("z = ")


def test_loop_shares_the_invariant_part(compile_src):
    prog = compile_src("var a, b;\nvar y[1..4];\nfor k in 1..4 { y[k] == sin(a + b) + k; }\n")
    c = ops(prog)
    assert c["sin"] == 1
    assert c["add"] == 1 + 4  # a + b once, then one `+ k` per iteration
    assert len(prog.primitives) == 6
    outs = {prog.slots.names[p.out[0]] for p in prog.primitives if p.op == "add"}
    assert {"y[1]", "y[2]", "y[3]", "y[4]"} <= outs


# -- constraints: binding, == between expressions, inequalities -------------------------------

@pytest.mark.parametrize("constraint", ["y1 == cos(a) + sin(a);", "cos(a) + sin(a) == y1;"])
def test_constraint_root_is_bound_to_the_declared_variable(compile_src, constraint):
    prog = compile_src(f"var a, y1 in [0.5, 1];\n{constraint}\n")
    assert len(prog.primitives) == 3  # cos, sin, and the add whose output is y1 itself
    root = next(p for p in prog.primitives if p.op == "add")
    assert root.out == (slot(prog, "y1"),)
    assert re.fullmatch(r"y1 = t\d+ \+ t\d+", render_primitive(root, prog.slots.names))
    assert prog.slots.kinds.count("temp") == 2


def test_equality_between_two_expressions_shares_one_slot(compile_src):
    prog = compile_src("var x, y;\nx + y == x * y;\n")
    assert ops(prog) == Counter({"add": 1, "mul": 1})
    add, mul = sorted(prog.primitives, key=lambda p: p.op)
    assert add.out == mul.out
    assert prog.slots.kinds[add.out[0]] == "temp"


def test_equality_of_two_variables_merges_them_and_intersects_domains(compile_src):
    prog = compile_src("var a in [0, 2];\nvar b in [1, 3];\na == b;\nvar z;\nz == sin(b);\n")
    s = prog.slots
    assert slot(prog, "a") == slot(prog, "b")
    assert (s.lo[slot(prog, "a")], s.hi[slot(prog, "a")]) == (1.0, 2.0)
    assert s.names[slot(prog, "b")] == "a"  # the first declared name names the slot
    assert texts(prog) == ["z = sin(a)"]


@pytest.mark.parametrize("rel, cap", [("<=", (-INF, 0.0)), (">=", (0.0, INF))])
def test_inequality_caps_the_difference_slot(compile_src, rel, cap):
    prog = compile_src(f"var x, y;\nx {rel} y;\n")
    assert len(prog.primitives) == 1
    p = prog.primitives[0]
    assert p.op == "sub"
    assert p.args == (slot(prog, "x"), slot(prog, "y"))
    assert (prog.slots.lo[p.out[0]], prog.slots.hi[p.out[0]]) == cap
    assert prog.slots.kinds[p.out[0]] == "temp"


def test_inequality_against_a_constant_contracts(compile_src):
    prog = compile_src("var x in [0, 10];\nvar y in [-5, 5];\nx <= 3;\ny >= x + 1;\n")
    res = propagate(prog, tol=0.0)
    x, y = slot(prog, "x"), slot(prog, "y")
    assert 3.0 <= res.hi[x] <= 3.0 + 1e-12
    assert 1.0 - 1e-12 <= res.lo[y] <= 1.0
    assert res.lo[x] == 0.0 and res.hi[y] == 5.0


def test_interval_right_hand_side_narrows_the_slot(compile_src):
    prog = compile_src("var x, y;\nx + y == [1, 2];\nx == 0.5 +- 0.25;\n")
    s = prog.slots
    (add,) = prog.primitives
    assert (s.lo[add.out[0]], s.hi[add.out[0]]) == (1.0, 2.0)
    assert (s.lo[slot(prog, "x")], s.hi[slot(prog, "x")]) == (0.25, 0.75)


def test_unused_expressions_make_no_primitive(compile_src):
    prog = compile_src("var x, y;\nlet dead = sin(x) * exp(y);\nvar z;\nz == cos(x);\n")
    assert texts(prog) == ["z = cos(x)"]
    assert prog.slots.declared_names == ["x", "y", "z"]  # unused y still has a slot


# -- congruence closure -----------------------------------------------------------------------

def test_congruence_closure_merges_primitives_made_identical(compile_src):
    prog = compile_src("var a, b, z1, z2;\nz1 == sin(a);\nz2 == sin(b);\na == b;\n")
    assert ops(prog) == Counter({"sin": 1})
    assert slot(prog, "z1") == slot(prog, "z2")


def test_congruence_closure_runs_to_its_fixed_point(compile_src):
    # exp(sin(a)) and exp(sin(b)) meet only after sin(a) and sin(b) have met
    prog = compile_src("var a, b, z1, z2;\nz1 == exp(sin(a)) + a;\nz2 == exp(sin(b)) + b;\n"
                       "a == b;\n")
    assert ops(prog) == Counter({"sin": 1, "exp": 1, "add": 1})
    assert slot(prog, "z1") == slot(prog, "z2")


@pytest.mark.parametrize("op", ["+", "*"])
def test_congruence_closure_merges_commuted_duplicates(compile_src, op):
    prog = compile_src(f"var a, b, c, d, z1, z2;\nz1 == a {op} d;\nz2 == b {op} c;\n"
                       "a == c;\nd == b;\n")
    assert slot(prog, "z1") == slot(prog, "z2")
    assert len(prog.primitives) == 1, texts(prog)




def test_variable_times_a_constant_equal_to_its_node_id_is_not_a_square(compile_src):
    # y is DAG node 1, so `y * 1` (and `y * (3 - 2)`, `y * 1.0`) compile to x = sqr(y)
    prog = compile_src("var x in [-10, 10];\nvar y in [2, 3];\nx == y * 1;\n")
    res = propagate(prog, tol=0.0)
    x = slot(prog, "x")
    assert res.lo[x] <= 2.0 and 3.0 <= res.hi[x]  # x = y: every value of [2, 3] is a solution


# -- constants --------------------------------------------------------------------------------

def test_exact_constants_fold_before_decomposition(compile_src):
    prog = compile_src("var x, y;\nx == y + (2 * 3 - (1 + 2) / 3);\n")
    assert texts(prog) == ["x = y + 5"]
    # no re-association: (y + 6) - 1 stays two primitives, as written
    assert len(compile_src("var x, y;\nx == y + 6 - 1;\n").primitives) == 2


@pytest.mark.parametrize("expr", [
    "y * 1",
    "y + 0", "1 * y", "--y", "y^1", "y - 0", "y / 1", "0 + y"])
def test_identities_leave_no_primitive(compile_src, expr):
    prog = compile_src(f"var x, y;\nx == {expr};\n")
    assert prog.primitives == []
    assert slot(prog, "x") == slot(prog, "y")


def test_transcendental_constants_fold_to_tight_enclosures(compile_src):
    prog = compile_src("var x, y;\nx == y * sin(1) + 2 * pi;\n")
    assert ops(prog) == Counter({"mul": 1, "add": 1})  # no sin primitive, no pi arithmetic
    s = prog.slots
    consts = [(s.lo[i], s.hi[i]) for i, k in enumerate(s.kinds) if k == "const"]
    assert len(consts) == 2
    for truth in (math.sin(1.0), 2 * math.pi):
        lo, hi = next(c for c in consts if c[0] <= truth <= c[1])
        assert hi - lo <= 64 * math.ulp(truth)  # a few ulps of libm error, rounded out


def test_x_times_zero_binds_the_variable_to_zero(compile_src):
    prog = compile_src("var x in [-1, 1];\nvar y;\nx == 0 * y;\n")
    assert prog.primitives == []
    x = slot(prog, "x")
    assert (prog.slots.lo[x], prog.slots.hi[x]) == (0.0, 0.0)


def test_constant_names_print_as_written():
    assert format_const(*sorted((np.nextafter(0.1, -1), 0.1))) == "0.1"
    assert format_const(3.0, 3.0) == "3"
    assert format_const(-INF, 2.0) == "[-oo, 2]"
    assert format_const(1.0, INF) == "[1, +oo]"


# -- the DAG API directly ---------------------------------------------------------------------

def test_decompose_from_a_hand_built_dag():
    dag = Dag()
    x = dag.var("x", 0.0, 1.0)
    y = dag.var("y", -INF, INF, kind="var")
    s = dag.op("add", x, y)
    dag.constrain(dag.op("sin", s), "==", dag.op("cos", dag.op("add", y, x)))
    dag.constrain(s, "<=", dag.const(2.0))
    slots, prims = decompose(Model("<dag>", dag))
    assert Counter(p.op for p in prims) == Counter({"add": 1, "sin": 1, "cos": 1, "sub": 1})
    sin = next(p for p in prims if p.op == "sin")
    cos = next(p for p in prims if p.op == "cos")
    assert sin.out == cos.out and sin.args == cos.args
    assert slots.declared_names == ["x", "y"]
    assert slots.kinds[:2] == ["param", "var"]
    assert all(p.loc is None for p in prims)


def test_every_live_slot_has_a_name_and_names_are_unique():
    prog = compile_model(elaborate(EXAMPLES / "language_tour.cal"))
    names = prog.slots.names
    assert all(names)
    non_const = [n for n, k in zip(names, prog.slots.kinds, strict=True) if k != "const"]
    assert len(non_const) == len(set(non_const))


# -- rotations --------------------------------------------------------------------------------

ROBOT = """param l in [0.5, 2] true 1;
var q in [-1, 1];
var px, py;
robot arm(a) { joint theta = a; joint d = l, theta = a; }
(arm(q) at (1, 0, 0))[1] == px;
(arm(q) at (1, 0, 0))[2] == py;
"""


def test_rotation_is_one_primitive_with_two_outputs(compile_src):
    prog = compile_src(ROBOT, formulation="rotation")
    assert ops(prog) == Counter({"rot": 2, "add": 1})
    rots = [p for p in prog.primitives if p.op == "rot"]
    assert all(len(p.out) == 2 and len(p.args) == 3 for p in rots)
    # the last rotation's two outputs are bound to the measured coordinates px, py
    assert rots[-1].out == (slot(prog, "px"), slot(prog, "py"))
    assert all(p.args[0] == slot(prog, "q") for p in rots)
    for p in rots:
        assert re.fullmatch(r"\(\S+, \S+\) = rot\(q, \(\S+, \S+\)\)",
                            render_primitive(p, prog.slots.names))


def test_matrix_formulation_has_no_rotation(compile_src):
    prog = compile_src(ROBOT, formulation="matrix")
    assert "rot" not in ops(prog)
    assert ops(prog)["cos"] == 1 and ops(prog)["sin"] == 1


def test_rotation_needed_for_one_output_only_still_has_both(compile_src):
    # only the x coordinate is constrained: the rotation still carries both outputs
    src = ROBOT.replace("(arm(q) at (1, 0, 0))[2] == py;\n", "")
    prog = compile_src(src, formulation="rotation")
    last = [p for p in prog.primitives if p.op == "rot"][-1]
    assert last.out[0] == slot(prog, "px")
    assert prog.slots.kinds[last.out[1]] == "temp"


def test_planar_arm_rotation_listing_counts():
    prog = compile_model(elaborate(EXAMPLES / "planar_arm.cal", formulation="rotation"))
    c = ops(prog)
    assert c["rot"] == 2 * 5  # two revolute joints, five configurations
    assert set(c) == {"rot", "add"}


# -- unification must not lose solutions -------------------------------------------------------

# Regression tests: an interval constant is a membership, not an identity (two constraints
# against the same interval, or two equal readings, must not make their sides equal).

def test_two_constraints_against_the_same_interval_keep_their_solutions(compile_src):
    prog = compile_src("var x in [-10, 10];\nvar y in [-10, 10];\nx + y == [0, 5];\n"
                       "x - y == [0, 5];\nx >= 2.5;\ny >= 1;\n")
    res = propagate(prog)
    assert res.status == "contracted"  # x = 3, y = 1 is a solution
    assert res.lo[slot(prog, "y")] <= 1.0 <= res.hi[slot(prog, "y")]


def test_equal_measurements_in_two_rows_stay_independent(compile_src):
    prog = compile_src("param p in [0, 1] true 0.45;\n"
                       'table m = "d.csv" { q : +- 0; x : +- 0.1; }\n'
                       "for k in 1..rows(m) { p + m.q[k] == m.x[k]; }\n",
                       files={"d.csv": "q,x\n0,0.5\n0.1,0.5\n"})
    res = propagate(prog)
    assert res.status == "contracted"  # p = 0.45: 0.45 and 0.55 are both 0.5 +- 0.1
    assert res.lo[slot(prog, "p")] <= 0.45 <= res.hi[slot(prog, "p")]


def test_point_constants_may_be_shared_soundly(compile_src):
    # x == 1 and y == 1 make x and y one slot: sound, they are the same number
    prog = compile_src("var x in [0, 5];\nvar y in [-5, 5];\nx == 1;\ny == 1;\nvar z;\n"
                       "z == x + y;\n")
    assert slot(prog, "x") == slot(prog, "y")
    res = propagate(prog)
    z = slot(prog, "z")
    assert res.status == "contracted"
    assert res.lo[z] <= 2.0 <= res.hi[z] and res.hi[z] - res.lo[z] < 1e-12
