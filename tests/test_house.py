"""The house's rules beside the layering, read from the source: a caller's settings reach
every module (none below the pipeline reads the process-wide `DEFAULT`), and no function
outside the public entry points takes a long argument list (a request is a dataclass)."""

from __future__ import annotations

import ast

import pytest

from tests.test_layering import ALL, PACKAGE, RANKS, stage

# their signatures are the user's options (calib_dsl.plan: the planning API)
ENTRY_POINTS = {"calib_dsl.cli", "calib_dsl.api", "calib_dsl.plan"}
MOST_PARAMETERS = 8


def reads_default(tree: ast.AST) -> list[int]:
    """Lines that import DEFAULT from calib_dsl.settings or read `<something>.DEFAULT`."""
    lines = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").endswith("settings"):
            lines += [node.lineno for a in node.names if a.name == "DEFAULT"]
        elif isinstance(node, ast.Attribute) and node.attr == "DEFAULT":
            lines.append(node.lineno)
    return lines


def parameters(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    a = node.args
    names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs]
    if names and names[0] in ("self", "cls"):
        names = names[1:]
    return len(names) + bool(a.vararg) + bool(a.kwarg)


BELOW = sorted(n for n in ALL if stage(n) and RANKS[stage(n)] < RANKS["pipeline"])


@pytest.mark.parametrize("name", BELOW)
def test_no_default_settings_below_the_pipeline(name):
    tree = ast.parse(ALL[name].read_text(encoding="utf-8"))
    found = reads_default(tree)
    assert not found, (f"{ALL[name].relative_to(PACKAGE.parent)}:{found[0]}: reads "
                       "settings.DEFAULT: take the caller's Settings instead")


def a_command(node: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    """A click command's callback (`@click.command(...)`, `@main.command()`): its
    parameters are the command line's options, as cli.py's are, wherever it lives."""
    for d in node.decorator_list:
        f = d.func if isinstance(d, ast.Call) else d
        if isinstance(f, ast.Attribute) and f.attr == "command":
            return True
    return False


@pytest.mark.parametrize("name", sorted(n for n in ALL if n not in ENTRY_POINTS))
def test_no_long_argument_lists(name):
    tree = ast.parse(ALL[name].read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and not a_command(node):
            count = parameters(node)
            assert count <= MOST_PARAMETERS, (
                f"{ALL[name].relative_to(PACKAGE.parent)}:{node.lineno}: {node.name} takes "
                f"{count} parameters (at most {MOST_PARAMETERS}: gather them in a dataclass)")


def test_the_checks_see_a_violation():
    bad = ast.parse("from calib_dsl.settings import DEFAULT\n"
                    "from calib_dsl import settings\n"
                    "x = settings.DEFAULT.tol\n"
                    "def f(a, b, c, d, e, f, g, h, *i): pass\n")
    assert reads_default(bad) == [1, 3]
    func = next(n for n in ast.walk(bad) if isinstance(n, ast.FunctionDef))
    assert parameters(func) == 9 > MOST_PARAMETERS
    assert "calib_dsl.lp.bounds" in BELOW and "calib_dsl.pipeline" not in BELOW


def test_the_words_are_their_text():
    """The enums of the results are str-valued: equal to their text, written as it in the
    JSON (so the documents do not change), and printed as it."""
    from calib_dsl.ir.status import Consistency, SlotKind, Status, Stop
    from calib_dsl.report.strict_json import dumps

    for enum in (Status, Stop, Consistency, SlotKind):
        for member in enum:
            assert member == member.value and f"{member}" == member.value
            assert dumps({"x": member}) == dumps({"x": member.value})
    assert Status("infeasible") is Status.INFEASIBLE and Stop("fixed point") is Stop.FIXED_POINT


# What `calibc solve` runs asks its Problem (calib_dsl/problem.py) for the model with other
# inputs (derived where the model allows): none of these elaborates or loads a model itself.
SOLVE_ROOMS = ("calib_dsl.outliers", "calib_dsl.analysis", "calib_dsl.strategy",
               "calib_dsl.inner", "calib_dsl.report", "calib_dsl.sections")
LOADERS = ("elaborate", "load_model", "compile_model")


def loads(tree: ast.AST) -> list[int]:
    """Lines that call `elaborate(`, `load_model(` or `compile_model(` (by any path)."""
    return [n.lineno for n in ast.walk(tree) if isinstance(n, ast.Call)
            and (getattr(n.func, "id", None) or getattr(n.func, "attr", None)) in LOADERS]


@pytest.mark.parametrize("name", sorted(n for n in ALL if n.startswith(SOLVE_ROOMS)))
def test_the_solve_rooms_never_elaborate(name):
    found = loads(ast.parse(ALL[name].read_text(encoding="utf-8")))
    assert not found, (f"{ALL[name].relative_to(PACKAGE.parent)}:{found[0]}: elaborates a "
                       "model: ask the Problem (problem.py: derive, without_rows, with_const)")


def test_the_load_check_sees_one():
    bad = ast.parse("from calib_dsl import problem\nm = elaborate('a.cal')\n"
                    "p = problem.load_model('a.cal')\n")
    assert loads(bad) == [2, 3]
    assert any(n.startswith("calib_dsl.outliers.") for n in ALL)
