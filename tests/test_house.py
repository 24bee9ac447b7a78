"""The house's rules beside the layering, read from the source: a caller's settings reach
every module (none below the pipeline reads the process-wide `DEFAULT`), and no function
outside the public entry points takes a long argument list (a request is a dataclass)."""

from __future__ import annotations

import ast

import pytest

from tests.test_layering import ALL, PACKAGE, RANKS, stage

# their signatures are the user's options
ENTRY_POINTS = {"calib_dsl.cli", "calib_dsl.api"}
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


# A result's words are compared as enum members (ir/status.py), never as their text: a typo
# in a member is an AttributeError, one in a string a comparison that is never true. A slot
# kind's word is flagged where it is compared with a kind (`.kind`, `kinds[i]`, `k`); the
# same words name the DAG's operators (`node.op == "var"`), which are not slot kinds.
def _words() -> tuple[set[str], set[str]]:
    from calib_dsl.ir.status import Consistency, SlotKind, Status, Stop

    results = {m.value for e in (Status, Stop, Consistency) for m in e if m.value}
    return results, {m.value for m in SlotKind}


RESULT_WORDS, KIND_WORDS = _words()
# comparisons of these words that stay text, with why
WORDS_LEFT = {
    ("calib_dsl.batch.jobs", "kind == 'data'"): "a job file's key (data, rows, exclude)",
}


def _texts(node: ast.expr) -> list[str]:
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return [node.value]
    if isinstance(node, ast.Tuple | ast.List | ast.Set):
        return [t for e in node.elts for t in _texts(e)]
    return []


def _a_kind(node: ast.expr) -> bool:
    text = ast.unparse(node)
    return "kind" in text or text == "k"


def words_compared(tree: ast.AST) -> list[tuple[int, str]]:
    """(line, source) of comparisons of a result's word, or of a slot kind's word with a
    kind, written as text; and of results built with one (`Result("infeasible", ...)`)."""
    found = []
    for n in ast.walk(tree):
        if isinstance(n, ast.Compare):
            sides = [n.left, *n.comparators]
            for side in sides:
                words = set(_texts(side))
                kinds = words & KIND_WORDS and any(_a_kind(o) for o in sides if o is not side)
                if words & RESULT_WORDS or kinds:
                    found.append((n.lineno, ast.unparse(n)))
                    break
        elif isinstance(n, ast.Call) and getattr(n.func, "id", None) in (
                "Result", "Outcome", "Solution"):
            if any(set(_texts(a)) & RESULT_WORDS for a in n.args):
                found.append((n.lineno, ast.unparse(n)))
    return found


@pytest.mark.parametrize("name", sorted(n for n in ALL if n != "calib_dsl.ir.status"))
def test_the_words_are_compared_as_members(name):
    found = [(line, text) for line, text in
             words_compared(ast.parse(ALL[name].read_text(encoding="utf-8")))
             if (name, text) not in WORDS_LEFT]
    assert not found, (f"{ALL[name].relative_to(PACKAGE.parent)}:{found[0][0]}: "
                       f"{found[0][1]}: compare with the member (ir/status.py's Status, Stop, "
                       "Consistency, SlotKind, UNKNOWNS)")


def test_the_word_check_sees_one():
    bad = ast.parse("if res.status == 'infeasible': pass\n"
                    "ok = s.kinds[i] in ('param', 'var')\n"
                    "if node.op == 'var': pass\n"
                    "r = Result('contracted', lo, hi, 0, 0.0, 'fixed point')\n"
                    "if res.status == Status.INFEASIBLE: pass\n")
    assert [line for line, _ in words_compared(bad)] == [1, 2, 4]
    assert all(k[0] in ALL for k in WORDS_LEFT)  # no stale entry

# What `calibc solve` runs asks its Problem (calib_dsl/problem.py) for the model with other
# inputs (derived where the model allows): none of these elaborates or loads a model itself.
SOLVE_ROOMS = ("calib_dsl.outliers", "calib_dsl.analysis", "calib_dsl.strategy",
               "calib_dsl.inner", "calib_dsl.report", "calib_dsl.sections")
LOADERS = ("elaborate", "load_model", "compile_model", "Elaborator")


def loads(tree: ast.AST) -> list[int]:
    """Lines that call `elaborate(`, `load_model(`, `compile_model(` or `Elaborator(` (by any
    path)."""
    return [n.lineno for n in ast.walk(tree) if isinstance(n, ast.Call)
            and (getattr(n.func, "id", None) or getattr(n.func, "attr", None)) in LOADERS]


@pytest.mark.parametrize("name", sorted(n for n in ALL if n.startswith(SOLVE_ROOMS)))
def test_the_solve_rooms_never_elaborate(name):
    found = loads(ast.parse(ALL[name].read_text(encoding="utf-8")))
    assert not found, (f"{ALL[name].relative_to(PACKAGE.parent)}:{found[0]}: elaborates a "
                       "model: ask the Problem (problem.py: derive, without_rows, with_const)")


def test_the_load_check_sees_one():
    bad = ast.parse("from calib_dsl import problem\nm = elaborate('a.cal')\n"
                    "p = problem.load_model('a.cal')\nrun = Elaborator('matrix')\n")
    assert loads(bad) == [2, 3, 4]
    assert any(n.startswith("calib_dsl.outliers.") for n in ALL)


# Module constants that are numbers: tuning constants belong in settings.py (a group per
# concern, passed down by the caller), so that a caller's Settings reaches them. A number
# that is not a choice of speed against tightness stays where it is used, named here with why.
TUNED_ROOMS = ("calib_dsl.strategy", "calib_dsl.relax", "calib_dsl.lp", "calib_dsl.inner",
               "calib_dsl.outliers", "calib_dsl.accuracy", "calib_dsl.plan",
               "calib_dsl.analysis", "calib_dsl.studies")
NOT_TUNING = {
    # floating point and its rounding: what makes a bound outward, not a choice
    "calib_dsl.relax.relaxation.RHS_REL": "a float dot product's rounding-error budget",
    "calib_dsl.relax.relaxation.RHS_ABS": "the same budget's absolute floor (underflow)",
    "calib_dsl.relax.models.U": "the unit roundoff",
    "calib_dsl.relax.models._SUM": "a summation's rounding factor",
    "calib_dsl.relax.models._TINY": "covers underflow in a remainder update",
    "calib_dsl.accuracy.statement._ULP": "a double's relative spacing",
    "calib_dsl.plan.classical.TINY": "a variance rounded to 0: its log, finite",
    "calib_dsl.plan.classical.EXCHANGE_GAIN": "log det's rounding: a smaller gain would cycle",
    "calib_dsl.plan.linear.ROUNDING": "a bound within the floats' width of its row's value",
    "calib_dsl.analysis.certify_point.ROUNDING_SPAN": "float bounds ulps off their exact values",
    "calib_dsl.studies.simulate.CHECK_RTOL": "true values satisfy a constraint to float error",
    "calib_dsl.studies.simulate.CHECK_ATOL": "the same check's absolute floor (values near 0)",
    "calib_dsl.analysis.unit_spreads.FACTORS": "units arithmetic: 1000 mm a m, 180/pi deg a rad",
    # encodings and the solver's own constants
    "calib_dsl.lp.highs.MANY_PIVOTS": "HiGHS's own 'no limit'",
    "calib_dsl.lp.highs.DUAL_SIMPLEX": "HiGHS's code for the dual simplex",
    "calib_dsl.inner.starts.CELL_KEY": "a key's radix: more columns than any table has",
    # guards on the input and what a report shows: no result depends on them
    "calib_dsl.accuracy.grid.MAX_POSES": "a grid this large is a mistake in its steps",
    "calib_dsl.accuracy.grid.MAX_VALUE": "a joint value this large is a typo (a float's inf)",
    "calib_dsl.accuracy.grid.MAX_CELLS": "poses x unknowns per row: a grid that fits in memory",
    "calib_dsl.studies.simulate.MAX_NODES": "rows x nodes per row: a campaign that fits in memory",
    "calib_dsl.plan.command.SWEEP_STEP": "what `--n A..B` means without a step (the CLI's)",
    "calib_dsl.outliers.rows.SHOWN": "rows the text report lists (the JSON has every one)",
    "calib_dsl.accuracy.batch_lp._BLOCK": "a memory block: the bounds are the same for any",
    "calib_dsl.analysis.certify_point.CHECK_CELLS": "a memory block: results the same for any",
    "calib_dsl.analysis.certify_point.CHUNK_CELLS": "a memory block: results the same for any",
    "calib_dsl.analysis.row_screen._BLOCK": "a memory block: each block's bounds rigorous",
    # what `calibc simulate --systematic` draws: the error model the data are made with (with
    # the seed, the file), not a choice of speed against tightness
    "calib_dsl.studies.campaign.TERMS": "sinusoids per column in the systematic error drawn",
    "calib_dsl.studies.campaign.MAX_FREQUENCY": "their largest frequency per joint (per turn)",
    "calib_dsl.studies.kinematics.RX90_TOOL": "the RX90 example robot's tool points: geometry",
}


def numeric(node: ast.expr) -> bool:
    """A number, or arithmetic on numbers (`2.0**-52`, `1 << 20`), or a tuple of them."""
    if isinstance(node, ast.Constant):
        return isinstance(node.value, int | float) and not isinstance(node.value, bool)
    if isinstance(node, ast.UnaryOp):
        return numeric(node.operand)
    if isinstance(node, ast.BinOp):
        return numeric(node.left) and numeric(node.right)
    if isinstance(node, ast.Tuple):
        return bool(node.elts) and all(numeric(e) for e in node.elts)
    return False


def numeric_constants(tree: ast.Module) -> list[tuple[str, int]]:
    """Module-level UPPER_CASE names bound to numbers, with their lines."""
    out = []
    for node in tree.body:
        targets = (node.targets if isinstance(node, ast.Assign)
                   else [node.target] if isinstance(node, ast.AnnAssign) else [])
        value = getattr(node, "value", None)
        for t in targets:
            if (isinstance(t, ast.Name) and t.id.lstrip("_").isupper() and value is not None
                    and numeric(value)):
                out.append((t.id, node.lineno))
    return out


@pytest.mark.parametrize("name", sorted(n for n in ALL if n.startswith(TUNED_ROOMS)))
def test_no_tuning_constant_outside_the_settings(name):
    tree = ast.parse(ALL[name].read_text(encoding="utf-8"))
    for const, line in numeric_constants(tree):
        assert f"{name}.{const}" in NOT_TUNING, (
            f"{ALL[name].relative_to(PACKAGE.parent)}:{line}: {const} is a number at module "
            "level: a tuning constant goes in settings.py (the group of its concern); one "
            "of arithmetic goes in tests/test_house.py's NOT_TUNING, with why")


def test_the_constant_check_sees_one():
    bad = ast.parse("A = 1\n_B: float = 2.0**-52\nC = (1.02, 1.5)\nD = 'x'\nE = f(1)\n"
                    "F = True\ng = 3\n")
    assert numeric_constants(bad) == [("A", 1), ("_B", 2), ("C", 3)]
    assert all(k.rpartition(".")[0] in ALL for k in NOT_TUNING)  # no stale entry
