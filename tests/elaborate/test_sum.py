"""`sum(k in a..b) body`: how it parses (precedence), what it elaborates to (exact while
constant, one DAG sum otherwise, vectors elementwise, 0 when empty), what the compiler and the
solver make of it, and its user errors (a message at the right place, exit 2)."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import pytest
from click.testing import CliRunner

from calib_dsl import cli
from calib_dsl.compile.group import compile_model
from calib_dsl.compile.listing import render_listing
from calib_dsl.elaborate.elaborator import elaborate
from calib_dsl.frontend import ast
from calib_dsl.frontend.diagnostics import CalError, Loc
from calib_dsl.frontend.parser import parse
from calib_dsl.pipeline import load, solve


def rhs(src: str) -> ast.Expr:
    (stmt,) = parse(f"x == {src};", "t.cal")
    assert isinstance(stmt, ast.Constraint)
    return stmt.rhs


def elab(tmp_path: Path, src: str, files: dict[str, str] | None = None):
    for name, text in (files or {}).items():
        (tmp_path / name).write_text(text, encoding="utf-8")
    path = tmp_path / "m.cal"
    path.write_text(src, encoding="utf-8")
    return elaborate(path)


# -- parsing -----------------------------------------------------------------------------------
def test_the_body_is_a_product_and_the_sum_a_term():
    e = rhs("sum(k in 1..n) a[k] * b[k] + c")
    assert isinstance(e, ast.BinOp) and e.op == "+"  # (sum of a[k] * b[k]) + c
    s = e.left
    assert isinstance(s, ast.SumOver) and s.var.id == "k"
    assert isinstance(s.body, ast.BinOp) and s.body.op == "*"
    assert s.range.lo.value == 1 and s.range.hi.id == "n"
    assert s.loc == Loc("t.cal", 1, 6) and s.var.loc == Loc("t.cal", 1, 10)


def test_sums_nest_and_follow_a_minus():
    e = rhs("a - sum(i in 1..2) sum(j in i..3) q[i][j] / 2")
    assert isinstance(e, ast.BinOp) and e.op == "-"
    outer = e.right
    assert isinstance(outer, ast.SumOver) and isinstance(outer.body, ast.SumOver)
    assert isinstance(outer.body.body, ast.BinOp) and outer.body.body.op == "/"
    assert isinstance(outer.body.range.lo, ast.Name)  # bounds may use the outer index


@pytest.mark.parametrize(("src", "message", "col"), [
    ("x == 2 * sum(k in 1..3) k;", "put it in parentheses, as in 2 * (sum(k in 1..n) x[k])",
     10),
    ("x == sum(k in 1..3);", "unexpected ';': expected an expression", 20),
    ("x == sum(k = 1..3) k;", "unexpected '=': expected 'in'", 12),
    ("var sum;", "'sum' is a reserved word", 5),
])
def test_syntax_errors(src, message, col):
    with pytest.raises(CalError) as err:
        parse(src, "t.cal")
    assert message in err.value.message
    assert err.value.loc == Loc("t.cal", 1, col)


# -- elaboration -------------------------------------------------------------------------------
def test_constant_sums_are_exact(tmp_path):
    model = elab(tmp_path, "const a = sum(k in 1..10) 1 / k;\nconst e = sum(k in 5..4) k;\n"
                           "const n = sum(i in 1..3) sum(j in 1..i) 1;\nvar x;\nx == a;\n")
    assert model.consts["a"] == sum(Fraction(1, k) for k in range(1, 11))
    assert model.consts["e"] == 0  # an empty range adds nothing
    assert model.consts["n"] == 6


def test_a_sum_of_unknowns_is_one_chain_of_adds(tmp_path):
    model = elab(tmp_path, "var x[1..4];\nvar s;\ns == sum(k in 1..4) x[k];\n")
    dag = model.dag
    (c,) = dag.constraints
    adds = [n for n in dag.nodes if n.op == "add"]
    assert len(adds) == 3  # x1 + x2 + x3 + x4: three additions, no 0 added first
    assert dag.nodes[c.rhs].op == "add"


def test_vector_bodies_add_elementwise(tmp_path):
    model = elab(tmp_path, "var u, v;\n(u, v) == sum(k in 1..3) (k, 2 * k);\n")
    consts = sorted(model.dag.nodes[c.rhs].data[:2] for c in model.dag.constraints)
    assert consts == [(6.0, 6.0), (12.0, 12.0)]


def test_the_index_is_local_and_may_shadow(tmp_path):
    model = elab(tmp_path, "const k = 100;\nconst s = sum(k in 1..3) k;\nconst t = k;\n"
                           "var x;\nx == s + t;\n")
    assert model.consts["s"] == 6 and model.consts["t"] == 100


@pytest.mark.parametrize(("src", "message", "line", "col"), [
    ("var x;\nx == sum(k in 1..5/2) k;", "a sum bound must be an integer, not 5/2", 2, 18),
    ("var n;\nvar x;\nx == sum(k in 1..n) k;", "a sum bound must be a constant integer; "
     "this depends on unknowns", 3, 18),
    ("var x;\nx == sum(k in 1..3) y[k];", "unknown name 'y'", 2, 21),
    ("var x;\nx == sum(k in 1..2) (k, k) + 0;", "cannot add a 2-vector and a number", 2, 6),
    ("var x;\nx == sum(i in 1..10000) sum(j in 1..10000) i;",
     "nested loops and sums of 100,000,000 iterations in all", 2, 25),
    ("var x;\nfor i in 1..10000 { x == sum(j in 1..10000) j; }",
     "nested loops and sums of 100,000,000 iterations in all", 2, 26),
])
def test_user_errors(tmp_path, src, message, line, col):
    with pytest.raises(CalError) as err:
        elab(tmp_path, src)
    assert message in err.value.message
    assert err.value.loc == Loc(str(tmp_path / "m.cal"), line, col)


# -- compile, solve, the command line ----------------------------------------------------------
# y = a + b x measured to +-1e-3 (the noise below is within it): the sums of the rows' own
# equations, and of x times them, pin a and b down
LINE = """param a in [-10, 10] true 1;
param b in [-10, 10] true 2;
table m = "line.csv" { x : +- 0; y : +- 1e-3; }
sum(k in 1..rows(m)) m.y[k] == sum(k in 1..rows(m)) (a + b * m.x[k]);
sum(k in 1..rows(m)) m.x[k] * m.y[k] == sum(k in 1..rows(m)) m.x[k] * (a + b * m.x[k]);
"""
NOISE = (0.0004, -0.0009, 0.0002, 0.0007, -0.0003)
CSV = "x,y\n" + "".join(f"{x},{1 + 2 * x + e!r}\n" for x, e in zip(range(1, 6), NOISE,
                                                                     strict=True))


def test_listing_and_solve_hold_the_truth(tmp_path):
    (tmp_path / "line.csv").write_text(CSV)
    (tmp_path / "line.cal").write_text(LINE)
    prog = load(tmp_path / "line.cal")
    listing = render_listing(prog)
    assert "line.cal:4" in listing and "line.cal:5" in listing
    assert listing == render_listing(compile_model(elaborate(tmp_path / "line.cal")))
    for strategy in ("hc4", "tight"):
        sol = solve(prog, strategy)
        assert sol.status == "contracted"
        for name, true in (("a", 1.0), ("b", 2.0)):
            i = prog.slots.names.index(name)
            assert sol.lo[i] <= true <= sol.hi[i]
            if strategy == "tight":
                assert sol.hi[i] - sol.lo[i] < 0.1  # narrowed from the domain's 20


def test_command_line_errors_exit_2(tmp_path):
    bad = tmp_path / "bad.cal"
    bad.write_text("var x;\nx == sum(k in 1..1/2) k;\n")
    for command in ("compile", "solve"):
        res = CliRunner().invoke(cli.main, [command, str(bad)])
        assert res.exit_code == 2
        assert f"{bad}:2:18: error: a sum bound must be an integer, not 1/2" in res.output
        assert "Traceback" not in res.output
