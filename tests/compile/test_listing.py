"""The listing `calibc compile` prints: header counts, declared unknowns, one primitive a line
with the model line it comes from."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from calib_dsl.compile.group import compile_model
from calib_dsl.compile.listing import listing_json, render_listing, render_primitive
from calib_dsl.elaborate.elaborator import Inputs, elaborate
from calib_dsl.frontend.diagnostics import Loc
from calib_dsl.ir.primitives import Primitive
from calib_dsl.ir.program import Program

EXAMPLES = Path(__file__).resolve().parents[2] / "models" / "examples"

NAME = r"[A-Za-z_][\w\[\]]*"


def load(name: str, formulation: str = "matrix", unroll: bool = False) -> Program:
    return compile_model(elaborate(EXAMPLES / name, formulation=formulation,
                                   inputs=Inputs(unroll=unroll)))


def primitive_lines(listing: str) -> list[str]:
    """The primitive lines of a listing, without the location comments."""
    body = listing.split("\nprimitives:\n", 1)[1]
    return [re.sub(r"\s+#.*$", "", line).strip() for line in body.splitlines() if line.strip()]


def match_eq25(lines: list[str]) -> dict[str, str]:
    """Match the six lines against the paper's eq. [25], whatever the temporaries are called:
    a1 = i1 + i2, a2 = cos(a1), a4 = sin(a1), a7 = sqr(a4), y1 = a2 + a4, y2 = i3 * a7."""
    assert len(lines) == 6, lines
    parsed = []
    for line in lines:
        m = re.fullmatch(rf"({NAME}) = (.+)", line)
        assert m, line
        parsed.append((m.group(1), m.group(2)))

    def find(pattern: str) -> tuple[str, re.Match]:
        hits = [(out, m) for out, rhs in parsed if (m := re.fullmatch(pattern, rhs))]
        assert len(hits) == 1, (pattern, lines)
        return hits[0]

    a1, _ = find(r"i1 \+ i2|i2 \+ i1")
    a2, _ = find(rf"cos\({re.escape(a1)}\)")
    a4, _ = find(rf"sin\({re.escape(a1)}\)")
    a7, _ = find(rf"sqr\({re.escape(a4)}\)|{re.escape(a4)}\^2")
    y1, _ = find(rf"{re.escape(a2)} \+ {re.escape(a4)}|{re.escape(a4)} \+ {re.escape(a2)}")
    y2, _ = find(rf"i3 \* {re.escape(a7)}|{re.escape(a7)} \* i3")
    assert (y1, y2) == ("y1", "y2")
    names = {"a1": a1, "a2": a2, "a4": a4, "a7": a7}
    assert len(set(names.values())) == 4  # four distinct temporaries
    return names


def test_paper_cse_listing_is_eq_25():
    text = render_listing(load("paper_cse.cal"))
    names = match_eq25(primitive_lines(text))
    assert all(re.fullmatch(r"t\d+", n) for n in names.values())


def test_eq_25_matcher_rejects_a_listing_without_cse():
    # the uncompiled eq. [24]: sin(i1 + i2) twice -- must not pass for eq. [25]
    eq24 = ["a1 = i1 + i2", "a2 = cos(a1)", "a3 = i1 + i2", "a4 = sin(a3)", "a5 = i1 + i2",
            "a6 = sin(a5)", "a7 = sqr(a6)", "y1 = a2 + a4", "y2 = i3 * a7"]
    with pytest.raises(AssertionError):
        match_eq25(eq24)
    with pytest.raises(AssertionError):
        match_eq25(["t1 = i1 + i2", "t2 = cos(t1)", "t3 = sin(t1)", "t4 = sqr(t3)",
                    "y1 = t2 + t3", "y2 = i3 + t4"])


def test_header_counts():
    prog = load("paper_cse.cal")
    lines = render_listing(prog).splitlines()
    assert lines[0] == "# calibc listing of " + prog.source + " (formulation: matrix)"
    assert lines[1] == "# 9 variables (5 declared, 4 temporaries), 0 constants"
    assert lines[2] == ("# 6 primitives in 6 groups over 5 levels: "
                        "add 2, cos 1, mul 1, sin 1, sqr 1")


def test_variables_section_lists_declared_unknowns_with_domains():
    text = render_listing(load("paper_cse.cal"))
    section = text.split("variables:\n", 1)[1].split("\n\nprimitives:", 1)[0].splitlines()
    rows = [re.fullmatch(r"\s+(\S+)\s+in (.+)\s+\((\w+)\)", line) for line in section[:5]]
    assert [(m.group(1), m.group(2).strip(), m.group(3)) for m in rows if m] == [
        ("i1", "[-oo, +oo]", "var"), ("i2", "[-oo, +oo]", "var"), ("i3", "[-oo, +oo]", "var"),
        ("y1", "[0.5, 1]", "var"), ("y2", "[-oo, +oo]", "var")]
    assert "(4 temporaries t1..t4" in section[5]


def test_fixed_unknown_and_param_kind(compile_src):
    text = render_listing(compile_src("param p in [0, 1] true 0.5;\nvar x in 3;\n"
                                      "var y;\ny == p * x;\n"))
    assert re.search(r"^  p\s+in \[0, 1\]  \(param\)$", text, re.M)
    assert re.search(r"^  x\s+in 3  \(var\)$", text, re.M)
    assert "temporaries" not in text.split("primitives:")[0].split("variables:")[1]


def test_each_primitive_line_names_its_model_line(compile_src):
    text = render_listing(compile_src("var a, b;\n\nvar y;\ny == sin(a) * b;\n\nb <= 2;\n"))
    lines = text.split("primitives:\n", 1)[1].splitlines()
    assert [re.search(r"# (\S+)$", line).group(1) for line in lines] == \
        ["m.cal:4", "m.cal:4", "m.cal:6"]


def test_listing_of_a_model_without_constraints(compile_src):
    text = render_listing(compile_src("var x in [0, 1];\n"))
    assert "# 0 primitives in 0 groups over 1 levels: \n" in text
    assert text.endswith("primitives:\n")


LOC = Loc("m.cal", 1, 1)
NAMES = ["x", "y", "z", "b", "u", "v"]


@pytest.mark.parametrize("op, out, args, param, text", [
    ("add", (2,), (0, 1), None, "z = x + y"),
    ("sub", (2,), (0, 1), None, "z = x - y"),
    ("mul", (2,), (0, 1), None, "z = x * y"),
    ("div", (2,), (0, 1), None, "z = x / y"),
    ("neg", (2,), (0,), None, "z = -x"),
    ("pow", (2,), (0,), 3.0, "z = x^3"),
    ("pow", (2,), (0,), 4.0, "z = x^4"),
    ("sqr", (2,), (0,), None, "z = sqr(x)"),
    ("sqrt", (2,), (0,), None, "z = sqrt(x)"),
    ("exp", (2,), (0,), None, "z = exp(x)"),
    ("log", (2,), (0,), None, "z = log(x)"),
    ("sin", (2,), (0,), None, "z = sin(x)"),
    ("cos", (2,), (0,), None, "z = cos(x)"),
    ("tan", (2,), (0,), None, "z = tan(x)"),
    ("abs", (2,), (0,), None, "z = abs(x)"),
    ("atan2", (2,), (0, 1), None, "z = atan2(x, y)"),
    ("rot", (4, 5), (3, 0, 1), None, "(u, v) = rot(b, (x, y))"),
])
def test_render_primitive(op, out, args, param, text):
    assert render_primitive(Primitive(op, out, args, param, LOC, 1), NAMES) == text


def test_rotation_listing_lines(compile_src):
    src = ("param l in [0.5, 2] true 1;\nvar q in [-1, 1];\nvar px, py;\n"
           "robot arm(a) { joint theta = a; joint d = l, theta = a; }\n"
           "(px, py) == ((arm(q) at (1, 0, 0))[1], (arm(q) at (1, 0, 0))[2]);\n")
    lines = primitive_lines(render_listing(compile_src(src, formulation="rotation")))
    assert lines[-1] == "(px, py) = rot(q, (t3, t2))"
    assert re.fullmatch(r"\(t1, t2\) = rot\(q, \(1, 0\)\)", lines[0])
    assert lines[1] in ("t3 = l + t1", "t3 = t1 + l")
    header = render_listing(compile_src(src, formulation="rotation")).splitlines()[0]
    assert header.endswith("(formulation: rotation)")


def test_listing_json_is_the_counts():
    prog = load("paper_propagation.cal")
    data = json.loads(listing_json(prog))
    assert data == prog.counts()
    assert set(data) == {"variables", "declared", "temporaries", "constants", "primitives",
                         "groups", "levels", "ops"}
    assert data["primitives"] == 2 and data["ops"] == {"pow": 1, "sin": 1}


def test_location_comments_line_up_at_most_60_columns_out():
    text = render_listing(load("planar_arm.cal", "rotation", unroll=True))
    lines = text.split("primitives:\n", 1)[1].splitlines()
    assert any(len(line.split("  # ")[0].strip()) > 60 for line in lines)  # some long ones
    columns = set()
    for line in lines:
        before, _, loc = line.partition("  # ")
        assert re.fullmatch(r"planar_arm\.cal:\d+", loc)
        if len(before.strip()) <= 60:
            columns.add(len(before))
    assert len(columns) == 1 and columns.pop() <= 2 + 60
