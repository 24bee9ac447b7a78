"""The .cal grammar and the AST it builds: every construct, precedence, locations, and
syntax errors (message and location)."""

from __future__ import annotations

import re
import tomllib
from fractions import Fraction
from pathlib import Path

import pytest

from calib_dsl.elaborate.elaborator import elaborate
from calib_dsl.frontend import ast, grammar
from calib_dsl.frontend.diagnostics import CalError, Loc
from calib_dsl.frontend.parser import parse, parse_file

ROOT = Path(__file__).resolve().parents[2]


def one(src: str) -> ast.Stmt:
    (stmt,) = parse(src, "t.cal")
    return stmt


def expr(src: str) -> ast.Expr:
    stmt = one(f"x == {src};")
    assert isinstance(stmt, ast.Constraint)
    return stmt.rhs


def show(e: ast.Expr) -> str:
    """A fully parenthesized rendering, to check precedence and associativity."""
    if isinstance(e, ast.Number):
        return e.text
    if isinstance(e, ast.Name):
        return e.id
    if isinstance(e, ast.Pi):
        return "pi"
    if isinstance(e, ast.Infinity):
        return "oo"
    if isinstance(e, ast.Neg):
        return f"(-{show(e.arg)})"
    if isinstance(e, ast.BinOp):
        return f"({show(e.left)} {e.op} {show(e.right)})"
    if isinstance(e, ast.Call):
        return f"{e.func}({', '.join(show(a) for a in e.args)})"
    if isinstance(e, ast.RobotAt):
        return f"{e.robot}({', '.join(show(a) for a in e.args)}) at {show(e.point)}"
    if isinstance(e, ast.Index):
        return f"{show(e.base)}[{show(e.index)}]"
    if isinstance(e, ast.Field):
        return f"{show(e.base)}.{e.name}"
    if isinstance(e, ast.TupleLit):
        return "<" + ", ".join(show(a) for a in e.items) + ">"
    if isinstance(e, ast.IntervalLit):
        return f"[{show(e.lo)}, {show(e.hi)}]"
    raise AssertionError(e)


# -- grammar location -------------------------------------------------------------------------
def test_grammar_found_in_source_checkout():
    assert grammar.grammar_path() == ROOT / "grammars" / "cal.lark"


def test_wheel_ships_grammar_where_the_loader_looks():
    conf = tomllib.loads((ROOT / "pyproject.toml").read_text())
    force = conf["tool"]["hatch"]["build"]["targets"]["wheel"]["force-include"]
    assert force["grammars"] == "calib_dsl/grammars"
    installed = grammar.CANDIDATES[0]
    package = Path(grammar.__file__).resolve().parent.parent  # calib_dsl/
    assert installed.relative_to(package) == Path("grammars/cal.lark")


def test_grammar_installed_copy_preferred(tmp_path, monkeypatch):
    inside, outside = tmp_path / "pkg" / "cal.lark", tmp_path / "repo" / "cal.lark"
    outside.parent.mkdir()
    outside.write_text("start: NAME")
    monkeypatch.setattr(grammar, "CANDIDATES", (inside, outside))
    assert grammar.grammar_path() == outside
    inside.parent.mkdir()
    inside.write_text("start: NAME")
    assert grammar.grammar_path() == inside


def test_grammar_missing_names_places(tmp_path, monkeypatch):
    monkeypatch.setattr(grammar, "CANDIDATES", (tmp_path / "a.lark", tmp_path / "b.lark"))
    with pytest.raises(FileNotFoundError, match="a.lark.*b.lark"):
        grammar.grammar_path()


# -- statements -------------------------------------------------------------------------------
def test_comments_and_whitespace_are_ignored():
    stmts = parse("# a comment\nconst N = 5;  # trailing\n\n   # another\n", "t.cal")
    assert len(stmts) == 1 and isinstance(stmts[0], ast.Const)


def test_const_let_def():
    c = one("const N = 50;")
    assert isinstance(c, ast.Const) and c.name.id == "N"
    assert c.value == ast.Number(Fraction(50), "50", Loc("t.cal", 1, 11))
    assert isinstance(one("let s = sin(a + b);"), ast.Let)
    d = one("def f(x, y) = x * cos(y);")
    assert isinstance(d, ast.Def) and [p.id for p in d.params] == ["x", "y"]
    assert show(d.body) == "(x * cos(y))"
    d0 = one("def g() = 1;")
    assert isinstance(d0, ast.Def) and d0.params == ()


def test_declarations():
    d = one("param r0 in [0.4, 0.6] true 0.5;")
    assert isinstance(d, ast.Decl) and d.kind == "param"
    assert [n.name.id for n in d.names] == ["r0"]
    assert show(d.domain) == "[0.4, 0.6]" and show(d.true) == "0.5"
    v = one("var i1, i2, i3 in [-oo, +oo];")
    assert v.kind == "var" and [n.name.id for n in v.names] == ["i1", "i2", "i3"]
    assert show(v.domain) == "[(-oo), oo]" and v.true is None
    bare = one("var y;")
    assert bare.domain is None and bare.true is None
    pm = one("param alpha1 in 0.1 +- 1e-5;")
    assert show(pm.domain) == "(0.1 +- 1e-5)"


def test_indexed_declarations():
    d = one("var q[1..6][1..N + 1], z in [-pi, pi];")
    q, z = d.names
    assert q.name.id == "q" and len(q.dims) == 2 and z.dims == ()
    assert show(q.dims[1].lo) == "1" and show(q.dims[1].hi) == "(N + 1)"


def test_for_loops_nest():
    f = one("for k in 1..N - 1 { x[k] == k; for j in 1..2 { y == j; } }")
    assert isinstance(f, ast.For) and f.var.id == "k"
    assert show(f.range.hi) == "(N - 1)"
    assert isinstance(f.body[0], ast.Constraint) and isinstance(f.body[1], ast.For)
    assert one("for k in 1..0 { }").body == ()


def test_include_and_relations():
    assert one('include "robot.cal";') == ast.Include("robot.cal", Loc("t.cal", 1, 1))
    for rel in ("==", "<=", ">=", "<", ">", "="):
        c = one(f"a {rel} b;")
        assert isinstance(c, ast.Constraint) and c.rel == rel
        assert c.rel_loc == Loc("t.cal", 1, 3)


def test_robot_definition():
    r = one("""robot arm(q1, q2) {
      base theta = t0, r = r0;
      joint alpha = a1, d = d1, theta = t1 + q1, r = r1;
      joint theta = q2;
    }""")
    assert isinstance(r, ast.Robot) and [p.id for p in r.params] == ["q1", "q2"]
    assert [f.kind for f in r.frames] == ["base", "joint", "joint"]
    assert [e.name.id for e in r.frames[1].entries] == ["alpha", "d", "theta", "r"]
    assert show(r.frames[1].entries[2].value) == "(t1 + q1)"
    assert r.frames[2].loc == Loc("t.cal", 4, 7)


def test_table_declaration():
    t = one("""table m = "data/m.csv" {
      q1, q2 : +- 1e-5 simulate in [-pi, pi];
      x : +- 1e-4;
    }""")
    assert isinstance(t, ast.TableDecl) and t.name.id == "m" and t.path == "data/m.csv"
    assert t.path_loc == Loc("t.cal", 1, 11)
    g1, g2 = t.groups
    assert [n.id for n in g1.names] == ["q1", "q2"] and show(g1.tol) == "1e-5"
    assert show(g1.simulate) == "[(-pi), pi]" and g2.simulate is None


# -- expressions ----------------------------------------------------------------------------
@pytest.mark.parametrize(("src", "tree"), [
    ("a + b * c", "(a + (b * c))"),
    ("a - b - c", "((a - b) - c)"),
    ("a / b / c", "((a / b) / c)"),
    ("-x^2", "(-(x ^ 2))"),
    ("2^3^2", "(2 ^ (3 ^ 2))"),
    ("x^-1", "(x ^ (-1))"),
    ("+x", "x"),
    ("--x", "(-(-x))"),
    ("a * -b", "(a * (-b))"),
    ("a + b +- c * d", "((a + b) +- (c * d))"),
    ("(a + b) * c", "((a + b) * c)"),
    ("(a, b + 1, c)", "<a, (b + 1), c>"),
    ("[-oo, 2 * pi]", "[(-oo), (2 * pi)]"),
    ("q[i + 1][2]", "q[(i + 1)][2]"),
    ("m.q1[k]", "m.q1[k]"),
    ("f() + atan2(y, x)", "(f() + atan2(y, x))"),
    ("rx90(q1, q2) at (1, 2, 3) + v", "(rx90(q1, q2) at <1, 2, 3> + v)"),
    ("r(q) at b[1]", "r(q) at b[1]"),
    ("sin(i1 + i2)^2", "(sin((i1 + i2)) ^ 2)"),
])
def test_precedence_and_associativity(src, tree):
    assert show(expr(src)) == tree


@pytest.mark.parametrize(("text", "value"), [
    ("0.1", Fraction(1, 10)), ("1e-5", Fraction(1, 100000)), ("2.5E+3", Fraction(2500)),
    ("007", Fraction(7)), ("12.50", Fraction(25, 2)),
])
def test_numbers_are_exact(text, value):
    n = expr(text)
    assert isinstance(n, ast.Number) and n.value == value and n.text == text


def test_range_dots_do_not_merge_with_numbers():
    f = one("for k in 1..3 { }")
    assert f.range.lo.value == 1 and f.range.hi.value == 3


def test_locations_point_at_the_start():
    stmts = parse("const N = 1;\n  let  a =\n    2 * x;\n", "dir/f.cal")
    assert stmts[0].loc == Loc("dir/f.cal", 1, 1)
    assert stmts[1].loc == Loc("dir/f.cal", 2, 3)
    assert stmts[1].name.loc == Loc("dir/f.cal", 2, 8)
    assert stmts[1].value.loc == Loc("dir/f.cal", 3, 5)
    assert stmts[1].value.right.loc == Loc("dir/f.cal", 3, 9)


def test_parse_file_reads_and_names(tmp_path):
    p = tmp_path / "m.cal"
    p.write_text("var x;\n")
    (d,) = parse_file(p)
    assert d.loc == Loc(str(p), 1, 1)


def test_parse_file_missing_or_binary(tmp_path):
    with pytest.raises(CalError, match="model file .*nope.cal' not found"):
        parse_file(tmp_path / "nope.cal")
    bad = tmp_path / "bin.cal"
    bad.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(CalError, match="not UTF-8"):
        parse_file(bad)


# -- syntax errors ----------------------------------------------------------------------------
@pytest.mark.parametrize(("src", "message", "line", "col"), [
    ("x == ;", "unexpected ';': expected an expression", 1, 6),
    ("const N = 50\nlet a = 1;", "missing ';' after number '50'", 1, 13),
    ("x == 1", "missing ';' after number '1'", 1, 7),
    ("x == (1, 2;", "unexpected ';': expected ')' or ','", 1, 11),
    ("for k in 1..3 { x == 1;", "unexpected end of file: expected a statement or '}'", 1, 24),
    ("const N == 2;", "'==' states a constraint; a definition uses '='", 1, 9),
    ("param in in [0, 1];", "'in' is a reserved word", 1, 7),
    ("var pi;", "'pi' is a reserved word", 1, 5),
    ("x == 1 $ 2;", "unexpected character '$'", 1, 8),
    ('include "abc;', "unterminated string", 1, 9),
    ("x == .5;", "unexpected '.': expected an expression (a number starts with a digit", 1, 6),
    ("x == 1 < 2;", "unexpected '<': expected ';'", 1, 8),
    (")", "unexpected ')': expected a statement", 1, 1),
    ("param x in [0, 1] true 1 2;", "unexpected number '2': expected an operator or ';'", 1, 26),
    ("robot r(q) { joint alpha == q; }", "'==' states a constraint", 1, 26),
    ("x == f(1,);", "unexpected ')': expected an expression", 1, 10),
])
def test_syntax_errors(src, message, line, col):
    with pytest.raises(CalError) as err:
        parse(src, "t.cal")
    assert message in err.value.message
    assert err.value.loc == Loc("t.cal", line, col)


def test_syntax_error_renders_with_caret(tmp_path):
    p = tmp_path / "bad.cal"
    p.write_text("var x;\nx == 2 * ;\n")
    with pytest.raises(CalError) as err:
        parse_file(p)
    text = err.value.render()
    assert text.startswith(f"{p}:2:10: error: unexpected ';'")
    assert text.splitlines()[1:] == ["    x == 2 * ;", "             ^"]


def test_deep_nesting_is_a_user_error(tmp_path):
    # the AST is built without recursion (Lark's non-recursive transformer)
    (c,) = parse("x == " + "-" * 5000 + "1;", "t.cal")
    assert isinstance(c.rhs, ast.Neg)
    path = tmp_path / "deep.cal"
    path.write_text("var x;\nx == " + "-" * 5000 + "x;\n")
    with pytest.raises(CalError, match="nests too deeply"):
        elaborate(path)
    # Parentheses alone add no depth to the tree.
    (c,) = parse("x == " + "(" * 3000 + "1" + ")" * 3000 + ";", "t.cal")
    assert c.rhs.value == 1


# -- the documentation and the shipped models parse ------------------------------------------
def test_every_cal_block_of_the_language_doc_parses():
    text = (ROOT / "docs" / "language.md").read_text()
    blocks = [body for lang, body in re.findall(r"```(\w*)\n(.*?)```", text, re.S) if not lang]
    assert len(blocks) >= 10
    for k, body in enumerate(blocks):
        assert parse(body, f"language.md block {k}") is not None


@pytest.mark.parametrize("path", sorted((ROOT / "models").rglob("*.cal")),
                         ids=lambda p: p.name)
def test_every_model_parses(path):
    assert parse_file(path)
