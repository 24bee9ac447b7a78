"""Every user error is a `CalError` with a clear message and a precise location; no Python
exception escapes for bad input (checked by fuzzing too)."""

from __future__ import annotations

import random
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib_dsl.elaborate.elaborator import elaborate
from calib_dsl.frontend.diagnostics import CalError, Loc

ROOT = Path(__file__).resolve().parents[1]
ROBOT = "robot r(q) { joint theta = q; }\n"
TABLE = 'table m = "d.csv" { a : +- 0; }\n'


def run(tmp_path: Path, src: str, name: str = "m.cal", **kw):
    (tmp_path / "d.csv").write_text("a,b\n1,2\n3,4\n")
    path = tmp_path / name
    path.write_text(src, encoding="utf-8")
    return elaborate(path, **kw)


def error_of(tmp_path: Path, src: str, **kw) -> CalError:
    with pytest.raises(CalError) as err:
        run(tmp_path, src, **kw)
    return err.value


# (source, part of the message, line, column) -- the location is in m.cal
CASES = [
    # names
    ("var x;\nx == y + 1;", "unknown name 'y'", 2, 6),
    ("param radius;\nradius == radiu;", "unknown name 'radiu' (did you mean 'radius'?)", 2, 11),
    ("var x;\nconst x = 1;", "'x' is already defined (at ", 2, 7),
    ("var a, a;", "'a' is already defined", 1, 8),
    ("def f(x, x) = x;", "duplicate parameter 'x'", 1, 10),
    ("robot r(q, q) { joint theta = q; }", "duplicate joint variable 'q'", 1, 12),
    ("const sin = 1;", "'sin' is a built-in function: choose another name", 1, 7),
    ("def f(cos) = 1;", "'cos' is a built-in function", 1, 7),
    ("var x; x == sqrt;", "'sqrt' is a built-in function: call it", 1, 13),
    # intervals and domains
    ("var x in [2, 1];", "empty interval: lower bound 2 is above upper bound 1", 1, 10),
    ("var x in [oo, 1];", "empty interval", 1, 10),
    ("var x in [-oo, -oo];", "an interval must hold a real number", 1, 10),
    ("var x in 1 +- -0.5;", "negative tolerance in '+-': -1/2", 1, 15),
    ("var x, y;\nx == y +- 1;", "the center of '+-' must be a constant", 2, 6),
    ("var x, y;\nx == 1 +- y;", "the tolerance of '+-' must be a constant", 2, 11),
    ("var x; var y in x;", "a domain must be a constant; this depends on unknowns", 1, 17),
    ("param p in [0, 1] true 2;", "true value 2.0 of 'p' is outside its domain [0.0, 1.0]", 1, 24),
    ("param p in [0, 1] true [0, 1];", "a true value must be a number, not an interval", 1, 24),
    ("const c = 0.5 +- 0.1;\nparam p in [0, 1] true c;", "a true value must be a number, not "
     "an interval [0.3999", 2, 24),
    ("param b[1..3] in [0, 1] true (0.1, 0.2);", "2 true values for 'b', which has 3", 1, 30),
    ("param p true (1, 2);", "'p' is a scalar: its true value is a number", 1, 14),
    ("var x; x == oo;", "'oo' (infinity) can only be a bound of an interval", 1, 13),
    ("var x; x == 1e300 * 1e300;", "number too large for a float", 1, 13),
    ("var x; x == 1e99999999;", "number 1e99999999 is out of range (exponent beyond +-400)",
     1, 13),
    ("var q[2..1];", "empty index range 2..1", 1, 6),
    # arguments
    ("var x; x == atan2(x);", "function 'atan2' takes 2 arguments, got 1", 1, 13),
    ("var x; x == sin(x, x);", "function 'sin' takes 1 argument, got 2", 1, 13),
    ("def f(a, b) = a;\nvar x; x == f(x);", "macro 'f' takes 2 arguments, got 1", 2, 13),
    (ROBOT + "var x; r(x, x) at (1, 2, 3) == (x, x, x);", "robot 'r' takes 1 joint value, got 2",
     2, 8),
    ("var x; x == dot(x, x);", "dot(u, v) takes two vectors, not a number and a number", 1, 13),
    # integers: loop bounds, indices, exponents
    ("for k in 1..5/2 { }", "a loop bound must be an integer, not 5/2", 1, 13),
    ("var n;\nfor k in 1..n { }", "a loop bound must be a constant integer; this depends on "
     "unknowns", 2, 13),
    ("for k in 1..pi { }", "a loop bound must be an integer", 1, 13),
    ("var x; x == x^0.5;", "an exponent must be an integer, not 1/2 (for a real power y, "
     "write exp(y * log(x)))", 1, 15),
    ("var x; x == x^x;", "an exponent must be a constant integer", 1, 15),
    ("var b[1..3]; b[4] == 0;", "index 4 out of range 1..3 of 'b'", 1, 16),
    ("var b[1..3]; b[0] == 0;", "index 0 out of range 1..3 of 'b'", 1, 16),
    ("var q[1..2][1..2]; q[1][3] == 0;", "index 3 out of range 1..2 of 'q'", 1, 25),
    ("var b[1..3]; b[1/2] == 0;", "an index must be an integer, not 1/2", 1, 16),
    ("var x; x[1] == 0;", "cannot index a number", 1, 8),
    ("var x; (x, x)[3] == 0;", "index 3 out of range 1..2 of a 2-vector", 1, 15),
    ("var q[1..2][1..2]; q[1][1] == q;", "'q' has 2 indices: give 1 more", 1, 31),
    # tables
    (TABLE + "var x; x == m.a[3];", "row 3 out of range 1..2 of table 'm'", 2, 17),
    (TABLE + "var x; x == m.b[1];", "table 'm' has no column 'b' (its columns: a)", 2, 13),
    (TABLE + "var x; x == m.a;", "'m.a' is a column: give a row, m.a[k]", 2, 13),
    (TABLE + "var x; x == m;", "'m' is a table: use a cell", 2, 13),
    ("var x; for k in 1..rows(x) { }", "rows(t) takes a table", 1, 25),
    ("var x; x.a[1] == 0;", "'.' selects a column of a table", 1, 8),
    ('table m = "d.csv" { a : +- -1; }', "a tolerance must be >= 0", 1, 28),
    ('table m = "d.csv" { a : +- oo; }', "'oo' (infinity) can only be a bound", 1, 28),
    ('table m = "d.csv" { a : +- 0 simulate in [-oo, 0]; }', "a simulation range must be "
     "finite", 1, 42),
    ('table m = "d.csv" { a, a : +- 0; }', "column 'a' is already declared", 1, 24),
    ('table m = "d.csv" { }', "table 'm' declares no column", 1, 1),
    ('var m;\ntable m = "d.csv" { a : +- 0; }', "'m' is already defined", 2, 7),
    # constraints
    ("var x;\nx = 3;", "'=' defines a name (const, let, def); a constraint is stated with '=='",
     2, 3),
    ("var x;\nx < 3;", "strict inequality '<' is not supported", 2, 3),
    ("var x;\nx > 3;", "means the same as '>='", 2, 3),
    ("var a, b; (a, b) == (a, b, a);", "cannot compare a 2-vector and a 3-vector", 1, 18),
    ("var a, b; (a, b) == a;", "cannot compare a 2-vector and a number", 1, 18),
    ("var a, b; (a, b) * (a, b) == 1;", "use dot(u, v)", 1, 11),
    ("var a, b; (a, b) / (a, b) == 1;", "cannot compute a 2-vector / a 2-vector", 1, 11),
    ("var a, b; (a, b) + 1 == 1;", "cannot add a 2-vector and a number", 1, 11),
    ("var a, b; sin((a, b)) == 1;", "an argument of sin must be a number, not a 2-vector", 1, 15),
    ("var a, b; ((a, b), a) == 1;", "vectors cannot be nested", 1, 12),
    ("var a; (a, a)^2 == 1;", "cannot raise a 2-vector to a power", 1, 8),
    ("var x; x == 1 / (2 - 2);", "division by zero", 1, 13),
    ("var x; x == 0^-1;", "division by zero (0 to a negative power)", 1, 13),
    ("var x; x == 2 * sqrt(-1);", "sqrt of these constants has no value (an argument is "
     "outside the function's domain)", 1, 17),
    ("var x; x == 1 + log([-2, 0]);", "log of these constants has no value", 1, 17),
    ("var x; x == 1 / [0, 0];", "the quotient of these constants has no value", 1, 13),
    ("var x; const c = x + 1;", "const 'c' depends on unknowns", 1, 18),
    # macros and robots
    ("def f(x) = f(x) + 1;\nvar y; y == f(y);", "macro 'f' calls itself (f -> f): macros are "
     "expanded inline, so recursion is not allowed", 1, 12),
    ("def f(x) = g(x);\ndef g(x) = 2 * f(x);\nvar y; y == f(y);", "(f -> g -> f)", 2, 16),
    ("def f(x) = x;\nvar y; y == f;", "'f' is a macro: call it, f(...)", 2, 13),
    ("var y; y == y(1);", "'y' is not a function or macro", 1, 13),
    (ROBOT + "var y; y == r(y);", "robot 'r' gives the coordinates of a tool point: write "
     "r(joint values) at (x, y, z)", 2, 13),
    (ROBOT + "var y; y == r;", "'r' is a robot: use it as r(joint values) at (x, y, z)", 2, 13),
    ("def f(x) = x;\nvar y; (y, y, y) == f(y) at (1, 2, 3);", "'f' is not a robot", 2, 21),
    (ROBOT + "var y; (y, y) == r(y) at (1, 2);", "a tool point is a 3-vector (x, y, z), not "
     "a 2-vector", 2, 26),
    (ROBOT + "var y; (y, y, y) == r((y, y)) at (1, 2, 3);", "a joint value must be a number",
     2, 23),
    ("robot r(q) { base alpha = q; joint theta = q; }", "a base frame has entries theta, r, not "
     "'alpha' (a modified-DH base frame has alpha = d = 0; or give the base as x, y, z, rx, "
     "ry, rz)", 1, 19),
    ("robot r(q) { base x = q, theta = 1; joint theta = q; }", "a base frame has entries x, "
     "y, z, rx, ry, rz, not 'theta'", 1, 26),
    ("robot r(q) { joint theta = q; base x = 1; }", "the base frames come first", 1, 31),
    ("robot r(q) { tool z = 1; joint theta = q; }", "the tool frames come last", 1, 26),
    ("robot r(q) { joint theta = q; tool alpha = 1; }", "a tool frame has entries x, y, z, rx, "
     "ry, rz, not 'alpha'", 1, 36),
    ("robot r(q) sdh { joint theta = q; }", "unknown convention 'sdh'", 1, 12),
    ("robot r(q) dh { joint theta = q, r = 1; }", "a joint frame has entries theta, d, a, "
     "alpha, not 'r'", 1, 34),
    ("robot r(q) { joint theta = q, theta = 1; }", "entry 'theta' given twice", 1, 31),
    ("robot r(q) { joint phi = q; }", "a joint frame has entries alpha, d, theta, r, not 'phi'",
     1, 20),
    ("robot r(q) { joint theta = q; base r = 1; }", "the base frames come first", 1, 31),
    ("robot r(q) { base theta = q; }", "robot 'r' has no joint", 1, 1),
    (ROBOT + "var y; r(y) at (1, 2, 3) == (y, y, zz);", "unknown name 'zz'", 2, 36),
    # top level only
    ("for k in 1..2 { var x; }", "a var declaration is only allowed at the top level", 1, 17),
    ("for k in 1..2 { param x; }", "a param declaration is only allowed", 1, 17),
    ('for k in 1..2 { include "x.cal"; }', "include is only allowed at the top level", 1, 17),
    ("for k in 1..2 { robot r(q) { joint theta = q; } }", "a robot definition is only", 1, 17),
    ('for k in 1..2 { table t = "d.csv" { a : +- 0; } }', "a table declaration is only", 1, 17),
    # includes
    ('include "nope.cal";', "include file 'nope.cal' not found (looked for ", 1, 1),
    ('include "m.cal";', "include cycle: ", 1, 1),
]


@pytest.mark.parametrize(("src", "message", "line", "col"), CASES,
                         ids=[c[1][:40] for c in CASES])
def test_user_error(tmp_path, src, message, line, col):
    err = error_of(tmp_path, src)
    assert message in err.message
    assert err.loc == Loc(str(tmp_path / "m.cal"), line, col)


def test_duplicate_message_names_the_first_definition(tmp_path):
    err = error_of(tmp_path, "var x;\nconst x = 1;")
    assert f"(at {tmp_path / 'm.cal'}:1:5)" in err.message


def test_include_cycle_through_two_files(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "b.cal").write_text('var y;\ninclude "../m.cal";\n')
    err = error_of(tmp_path, 'var x;\ninclude "sub/b.cal";\n')
    main, sub = str(tmp_path / "m.cal"), str(tmp_path / "sub" / "b.cal")
    assert err.message == f"include cycle: {main} -> {sub} -> {main}"
    assert err.loc == Loc(sub, 2, 1)


def test_errors_in_included_files_are_located_there(tmp_path):
    (tmp_path / "lib.cal").write_text("\n\nconst k = 1 / 0;\n")
    err = error_of(tmp_path, 'include "lib.cal";')
    assert err.loc == Loc(str(tmp_path / "lib.cal"), 3, 11)
    (tmp_path / "lib.cal").write_text("var x;\nx == ;\n")
    err = error_of(tmp_path, 'include "lib.cal";')
    assert err.loc == Loc(str(tmp_path / "lib.cal"), 2, 6)


def test_robot_entry_errors_point_into_the_robot(tmp_path):
    err = error_of(tmp_path, "robot r(q) {\n  joint theta = q + nothing;\n}\n"
                             "var y; r(y) at (1, 2, 3) == (y, y, y);")
    assert err.message.startswith("unknown name 'nothing'")
    assert err.loc == Loc(str(tmp_path / "m.cal"), 2, 21)


def test_renders_file_line_col_and_caret(tmp_path):
    err = error_of(tmp_path, "var x;\n  x = 3;\n")
    lines = err.render().splitlines()
    assert lines[0] == (f"{tmp_path / 'm.cal'}:2:5: error: '=' defines a name (const, let, "
                        "def); a constraint is stated with '==', as in `lhs == rhs;`")
    assert lines[1:] == ["      x = 3;", "        ^"]


# -- data files, options ------------------------------------------------------------------
def test_csv_errors_are_located_in_the_csv(tmp_path):
    (tmp_path / "bad.csv").write_text("a,b\n1,2\n3,x\n")
    with pytest.raises(CalError) as err:
        run(tmp_path, 'table m = "bad.csv" { a, b : +- 0; }')
    assert "row 2, column 'b': 'x' is not a number" in err.value.message
    assert err.value.loc == Loc(str(tmp_path / "bad.csv"), 3, 2)


def test_missing_csv_is_located_at_its_name_in_the_model(tmp_path):
    err = error_of(tmp_path, 'var x;\ntable m = "none.csv" { a : +- 0; }')
    assert err.message == f"data file '{tmp_path / 'none.csv'}' not found"
    assert err.loc == Loc(str(tmp_path / "m.cal"), 2, 11)


def test_missing_data_option_file(tmp_path):
    err = error_of(tmp_path, TABLE, data=str(tmp_path / "other.csv"))
    assert err.message == f"data file '{tmp_path / 'other.csv'}' not found" and err.loc is None


def test_bad_options_and_missing_model(tmp_path):
    with pytest.raises(CalError, match="unknown formulation 'quaternion'"):
        run(tmp_path, "var x;", formulation="quaternion")
    with pytest.raises(CalError, match="at least one row"):
        run(tmp_path, "var x;", simulate_rows=0)
    with pytest.raises(CalError, match="model file .* not found") as err:
        elaborate(tmp_path / "absent.cal")
    assert err.value.loc is None


def test_deep_expressions_are_user_errors(tmp_path):
    for depth in (300, 600, 2000, 20000):
        src = "var x; x == " + "-(" * depth + "x" + ")" * depth + ";"
        try:
            run(tmp_path, src)
        except CalError as err:
            assert "too deeply" in err.message
        else:
            assert depth <= 600  # shallow enough to elaborate


# -- fuzzing: whatever the input, a model or a CalError -------------------------------------
TOKENS = ["var", "param", "const", "let", "def", "for", "in", "true", "include", "robot",
          "base", "joint", "table", "simulate", "at", "pi", "oo", "x", "y", "k", "f", "r",
          "m", "m.a", "rows(m)", "0", "1", "2", "0.5", "1e-3", "+", "-", "*", "/", "^", "+-",
          "==", "<=", ">=", "=", "(", ")", "[", "]", "{", "}", ",", ";", "..", '"d.csv"',
          "sin", "sqr", "atan2", "dot", ":", "theta", "alpha", "r0"]
PRELUDE = ("var x, y; param r0 in [0, 1]; def f(u) = u * x;\n" + ROBOT + TABLE)


@given(st.lists(st.sampled_from(TOKENS), max_size=30))
@settings(max_examples=300, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_random_tokens_never_crash(tokens):
    with tempfile.TemporaryDirectory() as tmp:
        try:
            run(Path(tmp), PRELUDE + " ".join(tokens))
        except CalError:
            pass


def _mutants(text: str, seed: int, n: int) -> list[str]:
    rng = random.Random(seed)
    words = text.split(" ")
    out = []
    for _ in range(n):
        w = list(words)
        for _ in range(rng.randint(1, 3)):
            i = rng.randrange(len(w))
            w[i] = rng.choice(TOKENS + ["", w[rng.randrange(len(w))]])
        out.append(" ".join(w))
    return out


@pytest.mark.parametrize("example", ["planar_arm.cal", "circle_fit.cal"])
def test_mutated_examples_never_crash(tmp_path, example):
    source = ROOT / "models" / "examples" / example
    for f in source.parent.glob("*"):
        (tmp_path / f.name).write_bytes(f.read_bytes())
    for k, text in enumerate(_mutants(source.read_text(), seed=len(example), n=150)):
        (tmp_path / example).write_text(text)
        try:
            elaborate(tmp_path / example)
        except CalError:
            pass
        except Exception as exc:  # pragma: no cover - the failure report
            raise AssertionError(f"mutant {k} raised {exc!r}:\n{text}") from exc


# -- the bad inputs fuzzing found: one clear message, exit 2, at once ------------------------
BAD_COMMANDS = [
    (["solve", "{big}"], "number literal of 4400 digits"),
    (["solve", "{bigexp}"], "out of range"),
    (["solve", "{empty}"], "the model is empty"),
    (["compile", "{empty}"], "the model is empty"),
    (["solve", "{ok}", "--tol", "nan"], "not a finite number"),
    (["solve", "{ok}", "--tol", "-1"], "not a finite number"),
    (["simulate", "{ok}", "--configs", "3", "--seed", "-1", "-o", "{out}"], "x>=0"),
    (["simulate", "{ok}", "--configs", "10000000000", "--seed", "1", "-o", "{out}"],
     "1<=x<=1000000"),
    (["solve", "{nested}"], "nested loops of 100,000,000 iterations in all"),
    (["solve", "/dev/zero"], "is over 16 MiB: not a model"),
    (["solve", "{rx90}", "--data", "/dev/zero"], "is over 256 MiB: too large for a table"),
]


@pytest.mark.slow
@pytest.mark.parametrize("args, message", BAD_COMMANDS)
def test_bad_commands_exit_2_with_one_message(tmp_path, calibc, args, message):
    import subprocess

    files = {"big": "var x in [0, " + "1" * 4400 + "];\nx == 1;\n",
             "bigexp": "var x in [0, 1e" + "1" * 30 + "];\nx == 1;\n", "empty": "",
             "ok": "var x in [0, 2];\nx * x == 2;\n",
             "nested": "var x in [0, 1];\nfor i in 1..10000 { for j in 1..10000 { x <= 2; } }\n"}
    names = {k: str(tmp_path / f"{k}.cal") for k in files}
    for k, text in files.items():
        Path(names[k]).write_text(text)
    names["out"] = str(tmp_path / "out.csv")
    names["rx90"] = str(Path(__file__).resolve().parents[1] / "models" / "rx90_lengths.cal")
    out = subprocess.run([*calibc, *(a.format(**names) for a in args)], capture_output=True,
                         text=True, timeout=30)
    assert out.returncode == 2, (out.returncode, out.stderr)
    assert message in out.stderr and "Traceback" not in out.stderr


# -- warnings instead of silence --------------------------------------------------------------
@pytest.mark.parametrize("source, expected", [
    # nothing narrows: the constraint holds over the whole box
    ("param a in [0, 1];\nparam b in [0, 1];\na + b <= 5;\n", "no parameter was narrowed"),
    # a narrows, b keeps its whole domain
    ("param a in [0, 10];\nparam b in [0, 1];\na == 2 +- 0.1;\nb <= 5;\n",
     "1 of 2 parameters kept their whole search domain"),
])
def test_a_solve_that_learned_little_warns(tmp_path, calibc, source, expected):
    import json
    import subprocess

    path = tmp_path / "m.cal"
    path.write_text(source)
    out = subprocess.run([*calibc, "solve", str(path), "--json", "-"], capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert f"calibc: warning: {expected}" in out.stderr
    assert any(expected in w for w in json.loads(out.stdout)["warnings"])


def test_a_solve_that_narrowed_everything_does_not_warn(tmp_path, calibc):
    import json
    import subprocess

    path = tmp_path / "m.cal"
    path.write_text("param a in [0, 10];\na == 2 +- 0.1;\n")
    out = subprocess.run([*calibc, "solve", str(path), "--json", "-"], capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 0 and "warning" not in out.stderr
    assert json.loads(out.stdout)["warnings"] == []


def test_flat_sums_and_doubling_macros_elaborate(tmp_path, calibc):
    """A sum of 5000 terms is flat, not nested; macros that call the one below twice, 40
    levels deep, expand once per distinct call (linear, not 2^40)."""
    import subprocess

    flat = tmp_path / "flat.cal"
    flat.write_text("var x in [0, 1];\nx * 5000 == " + " + ".join(["x"] * 5000) + ";\n")
    doubling = tmp_path / "doubling.cal"
    doubling.write_text("var x in [0, 1];\ndef f0(u) = u + 1;\n"
                        + "".join(f"def f{i}(u) = f{i - 1}(u) * f{i - 1}(u);\n"
                                  for i in range(1, 41))
                        + "f40(x) >= 1;\n")
    for model in (flat, doubling):  # (2^40 expansions would not end before the timeout)
        out = subprocess.run([*calibc, "compile", str(model)], capture_output=True, text=True,
                             timeout=300)
        assert out.returncode == 0, out.stderr


# -- fuzzing the data: whatever a table holds, a result or one clear message ----------------
CELLS = ["0", "1.5", "-2", "1e300", "1e-320", "1e999", "nan", "NaN", "inf", "-inf", "",
         "1,5", "abc", '"3"', "0x10", "1.2.3", "--1", " 7 ", "1e", "9" * 40, "1;2"]
FUZZ_MODEL = """param a in [-10, 10];
param b in [-10, 10];
table m = "d.csv" { x : +- 0.001; y : +- 0.1; }
for k in 1..rows(m) { a * m.x[k] + b == m.y[k]; }
"""


@pytest.mark.slow
@given(st.lists(st.tuples(st.sampled_from(CELLS), st.sampled_from(CELLS)), max_size=8),
       st.sampled_from(["x,y", "y,x", "x", "x,y,z", "", "x,,y"]))
@settings(max_examples=200, deadline=30_000,  # a guard against hangs, not a speed test
          suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_any_table_gives_a_result_or_one_message(tmp_path, rows, header):
    """Random cells (numbers, NaN, infinities, garbage, quoting, too many separators) and
    headers: the model elaborates, compiles and solves, or says what is wrong in one
    CalError; never another exception."""
    from calib_dsl.compile.group import compile_model
    from calib_dsl.pipeline import solve

    (tmp_path / "d.csv").write_text(header + "\n" + "\n".join(f"{x},{y}" for x, y in rows)
                                    + "\n")
    (tmp_path / "m.cal").write_text(FUZZ_MODEL)
    try:
        prog = compile_model(elaborate(tmp_path / "m.cal"))
    except CalError:
        return
    assert solve(prog).status in ("contracted", "infeasible")


# -- fuzzing the command line: exit 0, 1 or 2, never a traceback ----------------------------
@given(st.lists(st.sampled_from(TOKENS), max_size=25),
       st.lists(st.tuples(st.sampled_from(CELLS), st.sampled_from(CELLS)), max_size=5),
       st.sampled_from([["solve", "--strategy", "hc4"], ["solve"], ["compile"],
                        ["identify"], ["solve", "--min-error", "e"]]))
@settings(max_examples=150, deadline=60_000,  # a guard against hangs, not a speed test
          suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_the_command_line_exits_0_1_or_2(tmp_path, tokens, rows, command):
    """Grammar-shaped models (the fuzz tokens after a prelude with a table) and random table
    contents through `calibc` itself: the exit code is 0, 1 or 2 and no traceback shows."""
    from click.testing import CliRunner

    from calib_dsl.cli import main

    (tmp_path / "d.csv").write_text("x,y\n" + "\n".join(f"{x},{y}" for x, y in rows) + "\n")
    (tmp_path / "m.cal").write_text("const e = 0.1;\n" + FUZZ_MODEL.replace("0.1", "e")
                                    + " ".join(tokens) + "\n")
    res = CliRunner().invoke(main, [*command[:1], str(tmp_path / "m.cal"), *command[1:],
                                    "--no-diagnose"] if command[0] == "solve" else
                             [command[0], str(tmp_path / "m.cal")])
    assert res.exit_code in (0, 1, 2), (res.exit_code, res.output)
    assert res.exception is None or isinstance(res.exception, SystemExit), res.exception
    assert "Traceback" not in res.output
