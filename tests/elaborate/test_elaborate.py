"""Elaboration: declarations, constants and folding, loops, macros, vectors, includes, tables,
simulation mode, robots, the paper's and the RX90 models, and speed."""

from __future__ import annotations

import math
import time
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calib_dsl.elaborate import chains as robot
from calib_dsl.elaborate.elaborator import Inputs, elaborate
from calib_dsl.frontend.diagnostics import CalError, Loc
from calib_dsl.ir.dag import Dag
from calib_dsl.studies.evaluate import evaluate

ROOT = Path(__file__).resolve().parents[2]
MODELS = ROOT / "models"


# -- helpers ----------------------------------------------------------------------------------
def elab(tmp_path, src: str, name: str = "m.cal", **kw):
    path = tmp_path / name
    path.write_text(src, encoding="utf-8")
    return elaborate(path, **kw)


def show(dag: Dag, n: int) -> str:
    """A node as text; the arguments of add and mul in sorted order (the DAG sorts by id)."""
    node = dag.nodes[n]
    if node.op == "var":
        return node.data
    if node.op == "const":
        lo, hi = node.data[:2]
        return repr(lo) if lo == hi else f"[{lo!r}, {hi!r}]"
    shown = [show(dag, a) for a in node.args]
    args = ", ".join(sorted(shown) if node.op in ("add", "mul") else shown)  # commutative
    return f"{node.op}{'' if node.data is None else node.data}({args})"


def sides(model) -> list[str]:
    dag = model.dag
    return [f"{show(dag, c.lhs)} {c.rel} {show(dag, c.rhs)}" for c in dag.constraints]


def encloses(node_data, exact: Fraction) -> bool:
    lo, hi = node_data
    return Fraction(lo) <= exact <= Fraction(hi)


# -- the paper's examples -------------------------------------------------------------------
def test_paper_cse_shares_sin():
    model = elaborate(MODELS / "examples" / "paper_cse.cal")
    dag = model.dag
    ops = sorted(n.op for n in dag.nodes if n.op not in ("var", "const"))
    assert ops == ["add", "add", "cos", "mul", "sin", "sqr"]  # the six primitives
    assert sides(model) == ["y1 == add(cos(add(i1, i2)), sin(add(i1, i2)))",
                            "y2 == mul(i3, sqr(sin(add(i1, i2))))"]
    assert [c.loc.line for c in dag.constraints] == [8, 9]
    assert {v.kind for v in dag.variables.values()} == {"var"}
    assert dag.variables["y1"].lo == 0.5 and dag.variables["y1"].hi == 1.0


def test_paper_propagation():
    model = elaborate(str(MODELS / "examples" / "paper_propagation.cal"))
    assert sides(model) == ["x1 == sin(x2)", "x1 == pow3(x2)"]
    assert model.path.endswith("paper_propagation.cal") and not model.simulation
    for v in model.dag.variables.values():
        assert (v.lo, v.hi, v.kind, v.true) == (-math.inf, math.inf, "var", None)


# -- declarations ---------------------------------------------------------------------------
def test_domains_true_values_and_kinds(tmp_path):
    model = elab(tmp_path, """
        param r0 in [0.4, 0.6] true 0.5;
        param alpha1 in 0.1 +- 1e-5;
        var u in [-oo, 0];
        var w in [1, oo];
        var free;
        param fixed in 3;
        param third in [0, 1] true 1/3;
    """)
    v = model.dag.variables
    assert v["r0"].kind == "param" and v["u"].kind == "var"
    assert Fraction(v["r0"].lo) <= Fraction("0.4") and Fraction(v["r0"].hi) >= Fraction("0.6")
    assert v["r0"].hi - v["r0"].lo < 0.2 + 1e-15 and v["r0"].true == 0.5
    lo, hi = Fraction(v["alpha1"].lo), Fraction(v["alpha1"].hi)
    assert lo <= Fraction("0.1") - Fraction("1e-5") < Fraction("0.1") + Fraction("1e-5") <= hi
    assert float(hi - lo) < 2e-5 + 1e-16
    assert v["alpha1"].true == 0.1  # the center of +-
    assert (v["u"].lo, v["u"].hi) == (-math.inf, 0.0)
    assert (v["w"].lo, v["w"].hi) == (1.0, math.inf)
    assert (v["free"].lo, v["free"].hi, v["free"].true) == (-math.inf, math.inf, None)
    assert (v["fixed"].lo, v["fixed"].hi, v["fixed"].true) == (3.0, 3.0, 3.0)
    assert v["third"].true == 1 / 3
    assert v["r0"].loc == Loc(str(tmp_path / "m.cal"), 2, 15)


def test_domain_with_pi_is_folded_outward(tmp_path):
    v = elab(tmp_path, "param t in pi/2 +- 1e-5; param a in [-pi, pi];").dag.variables
    assert v["t"].lo <= math.pi / 2 - 1e-5 and v["t"].hi >= math.pi / 2 + 1e-5
    assert v["t"].hi - v["t"].lo < 2e-5 + 1e-12
    assert v["t"].true == pytest.approx(math.pi / 2, abs=1e-15)
    assert v["a"].lo < -3.14159265358979 and v["a"].hi > 3.14159265358979


def test_families(tmp_path):
    model = elab(tmp_path, """
        const N = 2;
        param b[1..3] in [0, 0.2] true (0.1, 0.2, 0.1);
        var q[0..1][1..N + 1] in [-1, 1] true 0;
        var y[1..2];
        y[1] == b[2] + q[1][3];
        y == (b[1], b[3]);        # a 1-D family is a vector
    """)
    v = model.dag.variables
    assert [v[f"b[{i}]"].true for i in (1, 2, 3)] == [0.1, 0.2, 0.1]
    names = [n for n in v if n.startswith("q")]
    assert names == [f"q[{i}][{j}]" for i in (0, 1) for j in (1, 2, 3)]
    assert all(v[n].kind == "var" and v[n].true == 0 for n in names)
    assert sides(model) == ["y[1] == add(b[2], q[1][3])", "y[1] == b[1]", "y[2] == b[3]"]


# -- constants and folding --------------------------------------------------------------------
def test_exact_constant_arithmetic(tmp_path):
    model = elab(tmp_path, """
        const N = 50;
        const M = N / 2 + 2^3 - 7;    # exactly 26
        var x;
        for k in 1..M { x == k; }
        x == 1/3;
        x == 0.1;
        x == 2 * (3 + 1) - -1;
    """)
    rhs = [model.dag.nodes[c.rhs].data for c in model.dag.constraints]
    assert len(rhs) == 29
    assert rhs[:26] == [(float(k), float(k)) for k in range(1, 27)]
    third, tenth, nine = rhs[26:]
    assert encloses(third, Fraction(1, 3)) and third[1] == np.nextafter(third[0], 1)
    assert tenth == model.dag.nodes[model.dag.literal("0.1")].data
    assert nine == (9.0, 9.0)


def test_folded_constants(tmp_path):
    model = elab(tmp_path, """
        const h = pi / 2;
        var x;
        x == h;
        x == sin(h) + sqrt(4);
        x == [1, 2] * 2;
    """)
    dag = model.dag
    (h, s, iv) = [dag.nodes[c.rhs] for c in dag.constraints]
    assert h.op == s.op == iv.op == "const"
    assert h.data[0] <= math.pi / 2 <= h.data[1] and h.data[1] - h.data[0] < 1e-15
    assert s.data[0] <= 3.0 <= s.data[1]
    assert iv.data[0] <= 2.0 and iv.data[1] >= 4.0


@given(st.recursive(
    st.integers(0, 9).map(str),
    lambda inner: st.one_of(
        st.tuples(inner, st.sampled_from(["+", "-", "*", "/"]), inner).map(
            lambda t: f"({t[0]} {t[1]} {t[2]})"),
        inner.map(lambda e: f"-{e}"),
        st.tuples(inner, st.integers(-3, 3)).map(lambda t: f"({t[0]})^{t[1]}"),
    ), max_leaves=8))
@settings(max_examples=60, deadline=None)
def test_constant_arithmetic_is_exact(tmp_path_factory, text):
    """Any constant expression elaborates to the tightest enclosure of its exact value."""
    py = _as_fractions(text.replace("^", "**"))
    try:
        exact = Fraction(eval(py, {"F": Fraction, "__builtins__": {}}, {}))
    except ZeroDivisionError:
        exact = None
    tmp = tmp_path_factory.mktemp("c")
    if exact is None:
        with pytest.raises(CalError, match="division by zero"):
            elab(tmp, f"var x; x == {text};")
        return
    model = elab(tmp, f"var x; x == {text};")
    lo, hi = model.dag.nodes[model.dag.constraints[0].rhs].data
    assert Fraction(lo) <= exact <= Fraction(hi)
    assert lo == hi or hi == np.nextafter(lo, np.inf)


def _as_fractions(py: str) -> str:
    out, digits = [], ""
    for ch in py + " ":
        if ch.isdigit():
            digits += ch
            continue
        if digits:
            out.append(f"F({digits})")
            digits = ""
        out.append(ch)
    return "".join(out)


def test_huge_exact_powers_fall_back_to_intervals(tmp_path):
    start = time.process_time()  # this process's CPU: the same on a shared, busy machine
    model = elab(tmp_path, "var x; x == ((10^300)^300)^300 * x; x == (1/3)^2000 * x;")
    assert time.process_time() - start < 1.0  # not a 10^27000000 integer
    big, small = [model.dag.nodes[model.dag.nodes[c.rhs].args[1]].data
                  for c in model.dag.constraints]
    assert big[0] >= 1.7e308 and big[1] == math.inf  # sound: the value is beyond any float
    assert small[0] == 0.0 and 0 < small[1] < 1e-300


# -- operations ---------------------------------------------------------------------------
def test_powers_and_squares(tmp_path):
    model = elab(tmp_path, """
        var x, y;
        y == x * x;
        y == x^2;
        y == x^-2;
        y == x^0;
        y == x^1;
        y == x^(6/2);
        y == atan2(x, y) + abs(x) - tan(x) * exp(x) / log(x);
        y == -(-x);
    """)
    assert sides(model) == [
        "y == sqr(x)", "y == sqr(x)", "y == div(1.0, sqr(x))", "y == 1.0", "y == x",
        "y == pow3(x)", "y == sub(add(abs(x), atan2(x, y)), div(mul(exp(x), tan(x)), log(x)))",
        "y == x"]


def test_inequalities_and_interval_sides(tmp_path):
    model = elab(tmp_path, "var x; x <= 1; x >= -1; x == [-oo, 2]; x == 5 +- 0;")
    assert sides(model) == ["x <= 1.0", "x >= -1.0", "x == [-inf, 2.0]", "x == 5.0"]


# -- loops, lets, macros ----------------------------------------------------------------------
def test_nested_loops_and_per_iteration_let(tmp_path):
    model = elab(tmp_path, """
        var a, b, y[1..3][1..2];
        for i in 1..3 {
          let t = i * a;
          for j in 1..2 { y[i][j] == t + j; }
        }
        for k in 3..1 { a == k; }      # an empty range: no iteration
    """)
    assert len(model.dag.constraints) == 6
    assert sides(model)[0] == "y[1][1] == add(1.0, a)"
    assert sides(model)[5] == "y[3][2] == add(2.0, mul(3.0, a))"


def test_repeated_expressions_are_shared(tmp_path):
    model = elab(tmp_path, """
        var a, b, y[1..5];
        for k in 1..5 { y[k] == sin(a + b) * k; }
        y[1] == cos(a + b) + sin(a + b);
    """)
    ops = [n.op for n in model.dag.nodes]
    assert ops.count("sin") == 1 and ops.count("add") == 2 and ops.count("cos") == 1


def test_macros_expand_inline(tmp_path):
    model = elab(tmp_path, """
        def f(x, y) = x * cos(y);
        def g(x) = f(x, x) + c;        # c is defined after g: looked up when g is used
        var a, b, c, z;
        z == f(a, b);
        z == a * cos(b);
        z == g(a + 1);
        def scale(v, s) = s * v;       # vectors in and out
        (z, a) == scale((b, c), 2);
    """)
    s = sides(model)
    assert s[0] == s[1] == "z == mul(a, cos(b))"
    assert s[2] == "z == add(c, mul(add(1.0, a), cos(add(1.0, a))))"
    assert s[3:] == ["z == mul(2.0, b)", "a == mul(2.0, c)"]


def test_macro_parameters_shadow_and_scopes_nest(tmp_path):
    model = elab(tmp_path, """
        var x, y;
        def f(x) = x + 1;              # this x is the argument
        y == f(y);
        for k in 1..2 { let x = k; y == x; }   # a loop scope may shadow a global
        const x2 = 4;
        y == x2;
    """)
    assert sides(model) == ["y == add(1.0, y)", "y == 1.0", "y == 2.0", "y == 4.0"]


def test_macro_can_take_a_table_or_family(tmp_path):
    (tmp_path / "d.csv").write_text("a\n1\n2\n")
    model = elab(tmp_path, """
        table t = "d.csv" { a : +- 0; }
        var v[1..2];
        def cell(tab, k) = tab.a[k];
        def first(fam) = fam[1];
        for k in 1..rows(t) { v[k] == cell(t, k) + first(v); }
    """)
    assert sides(model) == ["v[1] == add(1.0, v[1])", "v[2] == add(2.0, v[1])"]


# -- vectors ----------------------------------------------------------------------------------
def test_vector_operations(tmp_path):
    model = elab(tmp_path, """
        var a, b, c, d;
        (a, b) + (c, d) == (1, 2);
        -(a, b) * 2 == (a, b) / 2 - (c, d);
        (a, b, c)[2] == dot((a, b), (c, d));
        let u = (a - c, b - d);
        dot(u, u) <= 1;
    """)
    assert sides(model) == [
        "add(a, c) == 1.0", "add(b, d) == 2.0",
        "mul(2.0, neg(a)) == sub(div(a, 2.0), c)", "mul(2.0, neg(b)) == sub(div(b, 2.0), d)",
        "b == add(mul(a, c), mul(b, d))",
        "add(sqr(sub(a, c)), sqr(sub(b, d))) <= 1.0"]


# -- include -------------------------------------------------------------------------------
def test_include_relative_with_own_locations(tmp_path):
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "common.cal").write_text("const K = 3;\n")
    (tmp_path / "lib" / "robot.cal").write_text(
        'include "common.cal";\n\nx == K;\ndef f(z) = z + K;\n')
    model = elab(tmp_path, 'var x;\ninclude "lib/robot.cal";\ninclude "lib/common.cal";\n'
                           'x == f(x);\n')
    first, second = model.dag.constraints
    assert first.loc == Loc(str(tmp_path / "lib" / "robot.cal"), 3, 1)
    assert second.loc == Loc(str(tmp_path / "m.cal"), 4, 1)
    assert sides(model) == ["x == 3.0", "x == add(3.0, x)"]  # common.cal included once


# -- tables --------------------------------------------------------------------------------
def table_model(tmp_path, **kw):
    (tmp_path / "data").mkdir(exist_ok=True)
    (tmp_path / "data" / "m.csv").write_text("q,x,extra\n0.5,1.25,a\n-1,2,b\n0.1,3,c\n")
    return elab(tmp_path, """
        var p;
        table m = "data/m.csv" {
          q : +- 1e-3 simulate in [-pi, pi];
          x : +- 0;
        }
        for k in 1..rows(m) { m.x[k] == p * m.q[k]; }
    """, **kw)


def test_table_cells_are_outward_intervals(tmp_path):
    model = table_model(tmp_path)
    (t,) = model.tables
    assert (t.name, t.rows, t.path) == ("m", 3, str(tmp_path / "data" / "m.csv"))
    assert [c.name for c in t.columns] == ["q", "x"]
    q, x = t.columns
    assert q.tol >= 1e-3 and q.tol - 1e-3 < 1e-18 and x.tol == 0
    assert q.sim[0] <= -math.pi and q.sim[1] >= math.pi and x.sim is None
    assert t.loc == Loc(str(tmp_path / "m.cal"), 3, 9)
    dag = model.dag
    c1 = dag.constraints[0]
    lhs = dag.nodes[c1.lhs].data
    assert encloses(lhs, Fraction("1.25")) and lhs[1] - lhs[0] < 1e-14
    q1 = dag.nodes[dag.nodes[c1.rhs].args[1]].data  # p * m.q[1]: [0.5 - 1e-3, 0.5 + 1e-3]
    assert q1[0] <= 0.499 and q1[1] >= 0.501 and q1[1] - q1[0] < 2e-3 + 1e-15
    assert len(dag.constraints) == 3 and not model.simulation
    assert ("m", "x", 1) in dag.cells[c1.lhs]  # each cell remembers where it was read
    assert ("m", "q", 3) in dag.cells[dag.nodes[dag.constraints[2].rhs].args[1]]


def test_data_option_replaces_the_csv(tmp_path):
    other = tmp_path / "other.csv"
    other.write_text("x,q\n7,1\n8,1\n")
    model = table_model(tmp_path, data=str(other))
    assert model.tables[0].path == str(other) and model.tables[0].rows == 2
    assert [show(model.dag, c.lhs) for c in model.dag.constraints] == ["7.0", "8.0"]


def test_simulation_mode_makes_cells_data_variables(tmp_path):
    (tmp_path / "data").mkdir()
    model = elab(tmp_path, """
        var p true 2;
        table m = "data/none_yet.csv" { q : +- 1e-3 simulate in [0, 1]; x : +- 0; }
        for k in 1..rows(m) { m.x[k] == p * m.q[k]; }
    """, simulate_rows=4)
    assert model.simulation and model.tables[0].rows == 4
    v = model.dag.variables
    cells = [n for n in v if n.startswith("m.")]
    assert cells == [f"m.q[{k}]" for k in range(1, 5)] + [f"m.x[{k}]" for k in range(1, 5)]
    assert all((v[n].kind, v[n].lo, v[n].hi) == ("data", -math.inf, math.inf) for n in cells)
    assert v["m.q[1]"].loc == Loc(str(tmp_path / "m.cal"), 3, 41)
    assert sides(model)[3] == "m.x[4] == mul(m.q[4], p)"


def test_data_without_table_is_an_error(tmp_path):
    with pytest.raises(CalError, match="model declares no table"):
        elab(tmp_path, "var x;", data="d.csv")


# -- robots -------------------------------------------------------------------------------
ARM = """
param t0, r0, a1, l1, l2 in [-10, 10];
robot arm(q1, q2) {
  base theta = t0, r = r0;
  joint alpha = a1, theta = q1;
  joint d = l1, theta = q2 + 1, r = 2 * q1;
}
var x, y, z, u, v;
arm(u, v) at (l2, 0, 1) == (x, y, z);
"""


def test_robot_use_builds_frames(tmp_path, monkeypatch):
    calls = []

    def fake(dag, frames, point, formulation):
        calls.append((frames, point, formulation))
        return dag.var("X", 0, 0), dag.var("Y", 0, 0), dag.var("Z", 0, 0)

    monkeypatch.setattr(robot, "forward_point", fake)
    model = elab(tmp_path, ARM, formulation="rotation")
    ((frames, point, formulation),) = calls
    dag = model.dag

    def entries(f):
        return [show(dag, n) for n in (f.alpha, f.d, f.theta, f.r)]

    assert formulation == "rotation" and model.formulation == "rotation"
    assert [entries(f) for f in frames] == [
        ["0.0", "0.0", "t0", "r0"],
        ["a1", "0.0", "u", "0.0"],
        ["0.0", "l1", "add(1.0, v)", "mul(2.0, u)"]]
    assert [show(dag, n) for n in point] == ["l2", "0.0", "1.0"]
    assert sides(model) == ["X == x", "Y == y", "Z == z"]


def test_robot_without_base_starts_at_identity(tmp_path, monkeypatch):
    seen = []
    monkeypatch.setattr(robot, "forward_point",
                        lambda dag, frames, p, f: seen.append(frames) or p)
    elab(tmp_path, "var q; robot r(j) { joint theta = j; } r(q) at (1, 2, 3) == (q, q, q);")
    base = seen[0][0]
    assert all(base.__dict__[k] == base.alpha for k in ("d", "theta", "r"))
    assert len(seen[0]) == 2


def test_robot_frames_built_once_per_configuration(tmp_path, monkeypatch):
    seen = []
    monkeypatch.setattr(robot, "forward_point",
                        lambda dag, frames, p, f: seen.append(id(frames)) or p)
    elab(tmp_path, """var q, a; robot r(j) { joint theta = j + a; }
        r(q) at (1, 2, 3) == (q, q, q);  r(q) at (4, 5, 6) == (q, q, q);
        r(q) at (1, 2, 3) == (a, a, a);""")
    assert len(seen) == 2 and seen[0] == seen[1]  # the third use is the first, reused


@pytest.mark.parametrize("formulation", ["matrix", "rotation"])
def test_planar_arm_kinematics_numerically(formulation):
    """The example's robot really is the planar arm: x = l1 cos q1 + l2 cos(q1 + q2)."""
    model = elaborate(MODELS / "examples" / "planar_arm.cal", formulation=formulation,
                      simulate_rows=2)
    dag = model.dag
    v = dag.variables
    q = {"m.q1[1]": 0.3, "m.q2[1]": -1.1, "m.q1[2]": 2.0, "m.q2[2]": 0.4}
    values = {v[n].node: x for n, x in q.items()} | {v["l1"].node: 1.0, v["l2"].node: 0.5}
    out = evaluate(dag, values, default=math.nan)
    by_lhs = {show(dag, c.rhs): out[c.lhs] for c in dag.constraints}
    for k in (1, 2):
        q1, q2 = q[f"m.q1[{k}]"], q[f"m.q2[{k}]"]
        assert by_lhs[f"m.x[{k}]"] == pytest.approx(math.cos(q1) + 0.5 * math.cos(q1 + q2))
        assert by_lhs[f"m.y[{k}]"] == pytest.approx(math.sin(q1) + 0.5 * math.sin(q1 + q2))


# -- the example models and the RX90 ----------------------------------------------------------
@pytest.mark.parametrize("name", ["language_tour", "circle_fit", "planar_arm", "paper_cse"])
def test_examples_elaborate(name):
    model = elaborate(MODELS / "examples" / f"{name}.cal")
    assert model.dag.constraints


LENGTHS = {"r0": (0.4, 0.6, 0.5), "d1": (0, 0.1, 0), "r1": (0, 0.1, 0),
           "d3": (0.49, 0.51, 0.5), "r4": (0.49, 0.51, 0.5),
           "b1x": (0, 0.2, 0.1), "b1y": (0.1, 0.3, 0.2), "b1z": (0, 0.2, 0.1),
           "b2x": (0, 0.2, 0.1), "b2y": (0, 0.2, 0.1), "b2z": (0.1, 0.3, 0.2),
           "b3x": (0.1, 0.3, 0.2), "b3y": (0, 0.2, 0.1), "b3z": (0, 0.2, 0.1)}
KNOWN = {"theta0": math.pi / 2, "alpha1": 0.1, "theta1": 0, "d2": 0, "alpha2": -math.pi / 2,
         "theta2": 0, "r2": 0, "alpha3": 0, "theta3": 0, "r3": 0, "d4": 0,
         "alpha4": math.pi / 2, "theta4": 0, "alpha5": -math.pi / 2, "d5": 0, "theta5": 0,
         "r5": 0, "alpha6": math.pi / 2, "d6": 0}


def params(model):
    return {n: v for n, v in model.dag.variables.items() if v.kind == "param"}


def test_rx90_lengths_model():
    model = elaborate(MODELS / "rx90_lengths.cal", simulate_rows=2)
    p = params(model)
    assert set(p) == set(LENGTHS) | set(KNOWN) and len(p) == 33
    for name, (lo, hi, true) in LENGTHS.items():
        assert p[name].lo == pytest.approx(lo, abs=1e-15)
        assert p[name].hi == pytest.approx(hi, abs=1e-15) and p[name].true == true
    for name, true in KNOWN.items():
        assert p[name].true == pytest.approx(true, abs=1e-15)
        assert p[name].lo <= true - 1e-5 and p[name].hi >= true + 1e-5
        assert p[name].hi - p[name].lo < 2e-5 + 1e-12
    (t,) = model.tables
    assert t.path == str(Path(MODELS / "data" / "rx90_50.csv"))
    assert [c.name for c in t.columns] == [f"q{j}" for j in range(1, 7)] + [
        f"a{i}{c}" for i in (1, 2, 3) for c in "xyz"]
    assert len(model.dag.constraints) == 9 * 2 + 3


def test_rx90_full_model():
    model = elaborate(MODELS / "rx90_full.cal", simulate_rows=1)
    p = params(model)
    assert set(p) == set(LENGTHS) | set(KNOWN)
    base = {"theta0", "r0", "alpha1", "d1", "theta1", "r1"} | {
        f"b{i}{c}" for i in (1, 2, 3) for c in "xyz"}
    for name, var in p.items():
        angle = name.startswith(("alpha", "theta"))
        half = (0.17 if angle else 0.1) if name in base else (0.035 if angle else 0.01)
        assert var.true == pytest.approx({**KNOWN, **{k: t for k, (_, _, t) in
                                                      LENGTHS.items()}}[name], abs=1e-15)
        assert var.lo == pytest.approx(var.true - half, abs=1e-12)
        assert var.hi == pytest.approx(var.true + half, abs=1e-12)


def test_rx90_reads_a_csv(tmp_path):
    cols = [f"q{j}" for j in range(1, 7)] + [f"a{i}{c}" for i in (1, 2, 3) for c in "xyz"]
    rows = [",".join(str(0.1 * (j + k)) for j in range(15)) for k in range(3)]
    (tmp_path / "d.csv").write_text(",".join(cols) + "\n" + "\n".join(rows) + "\n")
    model = elaborate(MODELS / "rx90_lengths.cal", data=tmp_path / "d.csv",
                      inputs=Inputs(unroll=True))
    assert model.tables[0].rows == 3 and len(model.dag.constraints) == 9 * 3 + 3
    assert not [v for v in model.dag.variables.values() if v.kind == "data"]


# -- speed --------------------------------------------------------------------------------
def test_thousand_configurations_elaborate_fast(tmp_path, monkeypatch):
    """The front end's own cost on the RX90 model with 1000 rows (the chain is robot.py's)."""
    monkeypatch.setattr(robot, "forward_point", lambda dag, frames, p, f: p)
    cols = [f"q{j}" for j in range(1, 7)] + [f"a{i}{c}" for i in (1, 2, 3) for c in "xyz"]
    rng = np.random.default_rng(0)
    lines = [",".join(repr(x) for x in row) for row in rng.uniform(-1, 1, (1000, 15)).tolist()]
    (tmp_path / "d.csv").write_text(",".join(cols) + "\n" + "\n".join(lines) + "\n")
    start = time.process_time()  # this process's CPU: the same on a shared, busy machine
    model = elaborate(MODELS / "rx90_lengths.cal", data=tmp_path / "d.csv",
                      inputs=Inputs(unroll=True))
    elapsed = time.process_time() - start
    assert len(model.dag.constraints) == 9 * 1000 + 3
    assert elapsed < 2.0
