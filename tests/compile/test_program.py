"""The flat program: primitives grouped by (level, op) into integer arrays the propagator runs
with a few numpy calls per group."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from calib_dsl.compile.group import compile_model, make_groups
from calib_dsl.elaborate.elaborator import elaborate
from calib_dsl.ir.program import Program
from calib_dsl.propagate.fixpoint import propagate

EXAMPLES = Path(__file__).resolve().parents[2] / "models" / "examples"

MODELS = [("paper_cse.cal", "matrix"), ("paper_propagation.cal", "matrix"),
          ("circle_fit.cal", "matrix"), ("language_tour.cal", "matrix"),
          ("planar_arm.cal", "matrix"), ("planar_arm.cal", "rotation")]
LEAF_KINDS = ("param", "var", "data", "const")


def load(name: str, formulation: str = "matrix") -> Program:
    return compile_model(elaborate(EXAMPLES / name, formulation=formulation))


def check_groups(prog: Program) -> None:
    """The group arrays say exactly what the primitive list says."""
    seen = np.concatenate([g.prim for g in prog.groups]) if prog.groups else np.array([], int)
    assert sorted(seen.tolist()) == list(range(len(prog.primitives)))  # each exactly once
    keys = [(g.level, g.op) for g in prog.groups]
    assert keys == sorted(keys) and len(set(keys)) == len(keys)
    for g in prog.groups:
        n = len(g.prim)
        arity = 3 if g.op == "rot" else len(prog.primitives[int(g.prim[0])].args)
        assert g.out.shape == (n, 2 if g.op == "rot" else 1)
        assert g.args.shape == (n, arity)
        assert g.out.dtype == np.int64 and g.args.dtype == np.int64
        for row, i in enumerate(g.prim):
            p = prog.primitives[int(i)]
            assert (p.op, p.level) == (g.op, g.level)
            assert tuple(g.out[row]) == p.out
            assert tuple(g.args[row]) == p.args
            if g.op == "pow":
                assert g.param is not None and g.param[row] == p.param
        if g.op != "pow":
            assert g.param is None
        for col, flag in zip(g.out.T, g.out_unique, strict=True):
            assert flag == (len(set(col.tolist())) == len(col))
        for col, flag in zip(g.args.T, g.args_unique, strict=True):
            assert flag == (len(set(col.tolist())) == len(col))
        assert len(g.out_unique) == g.out.shape[1] and len(g.args_unique) == g.args.shape[1]


def level_violations(prog: Program) -> list[str]:
    """Arguments of a level-L primitive that are neither a leaf (declared unknown, data,
    constant) nor produced by some primitive of a lower level."""
    produced: dict[int, int] = {}
    for p in prog.primitives:
        for s in p.out:
            produced[s] = min(produced.get(s, p.level), p.level)
    bad = []
    for p in prog.primitives:
        for s in p.args:
            if prog.slots.kinds[s] in LEAF_KINDS:
                continue
            if produced.get(s, p.level) >= p.level:
                bad.append(f"{prog.slots.names[s]} used at level {p.level}")
    return bad


@pytest.mark.parametrize("name, formulation", MODELS)
def test_groups_are_consistent_with_primitives(name, formulation):
    check_groups(load(name, formulation))


@pytest.mark.parametrize("name, formulation", MODELS)
def test_level_order_is_respected(name, formulation):
    prog = load(name, formulation)
    assert level_violations(prog) == []
    for p in prog.primitives:  # a leaf-only primitive is at level 1, never 0
        assert p.level >= 1


@pytest.mark.parametrize("name, formulation", MODELS)
def test_counts_agree_with_the_program(name, formulation):
    prog = load(name, formulation)
    c = prog.counts()
    kinds = Counter(prog.slots.kinds)
    assert c["primitives"] == len(prog.primitives) == sum(c["ops"].values())
    assert c["groups"] == len(prog.groups)
    assert c["levels"] == 1 + max(g.level for g in prog.groups)
    assert c["constants"] == kinds["const"] and c["temporaries"] == kinds["temp"]
    assert c["variables"] == len(prog.slots.names) - kinds["const"]
    assert c["declared"] == len(prog.slots.declared_names)
    assert c["ops"] == dict(sorted(Counter(p.op for p in prog.primitives).items()))


def test_paper_cse_groups():
    prog = load("paper_cse.cal")
    assert [(g.level, g.op, len(g.prim)) for g in prog.groups] == [
        (1, "add", 1), (2, "cos", 1), (2, "sin", 1), (3, "add", 1), (3, "sqr", 1),
        (4, "mul", 1)]


def test_same_op_same_level_share_a_group(compile_src):
    prog = compile_src("var a, b, c, d;\nvar u, v, w;\nu == a + b;\nv == c + d;\nw == a + c;\n")
    (g,) = prog.groups
    assert (g.op, g.level, len(g.prim)) == ("add", 1, 3)
    # first arguments a, c, a (a repeats); second arguments b, d, c (all distinct)
    assert g.out_unique == (True,)
    assert g.args_unique == (False, True)
    check_groups(prog)


def test_uniqueness_flags_for_repeated_slots(compile_src):
    prog = compile_src("var a, b, c, d, t;\nt == a + b;\nt == c + d;\nvar z1, z2;\n"
                       "z1 == a * c;\nz2 == a * d;\n")
    check_groups(prog)
    add = next(g for g in prog.groups if g.op == "add")
    mul = next(g for g in prog.groups if g.op == "mul")
    assert add.out_unique == (False,)  # t is the output of both additions
    assert add.args_unique == (True, True)
    assert mul.out_unique == (True,)
    assert False in mul.args_unique  # a is an argument of both products


def test_repeated_output_slot_intersects_every_projection(compile_src):
    # t = a + b in [0, 2] and t = c + d in [1.5, 4]: t in [1.5, 2], and back to a and b
    prog = compile_src("var a, b in [0, 1];\nvar c, d in [0.75, 2];\nvar t;\n"
                       "t == a + b;\nt == c + d;\n")
    res = propagate(prog, tol=0.0)
    s = prog.slots
    t = s.declared[s.declared_names.index("t")]
    a = s.declared[s.declared_names.index("a")]
    assert res.status == "contracted"
    assert 1.5 - 1e-12 <= res.lo[t] <= 1.5 and 2.0 <= res.hi[t] <= 2.0 + 1e-12
    assert 0.5 - 1e-12 <= res.lo[a] <= 0.5


def test_pow_group_carries_the_exponents(compile_src):
    prog = compile_src("var x, y, z, w;\ny == x^3;\nz == x^5;\nw == x^-4;\n")
    check_groups(prog)
    (g,) = [g for g in prog.groups if g.op == "pow"]
    assert sorted(g.param.tolist()) == [3.0, 4.0, 5.0]
    assert g.param.dtype == float
    assert Counter(p.op for p in prog.primitives) == Counter({"pow": 3, "div": 1})


def test_level_is_one_more_than_the_deepest_argument(compile_src):
    prog = compile_src("var x, y;\ny == exp(sin(cos(x)) + x);\n")
    assert [(p.op, p.level) for p in prog.primitives] == [
        ("cos", 1), ("sin", 2), ("add", 3), ("exp", 4)]


def test_level_order_survives_congruence_closure(compile_src):
    prog = compile_src("var a, q, z, y;\ny == sin(cos(cos(a))) + 1;\nz == sin(q) * 2;\n"
                       "q == cos(cos(a));\n")
    assert level_violations(prog) == []


def test_make_groups_of_nothing():
    assert make_groups([]) == []


def test_compiling_twice_gives_the_same_program():
    model = elaborate(EXAMPLES / "language_tour.cal")
    a, b = compile_model(model), compile_model(model)
    assert [(p.op, p.out, p.args, p.param) for p in a.primitives] == \
        [(p.op, p.out, p.args, p.param) for p in b.primitives]
    assert a.slots.names == b.slots.names
    assert np.array_equal(a.slots.lo, b.slots.lo) and np.array_equal(a.slots.hi, b.slots.hi)


def test_true_values_and_source(compile_src):
    prog = compile_src("param p in [0, 1] true 0.25;\nvar x;\nx == sin(p);\n")
    assert prog.true_values == {"p": 0.25, "x": None}
    assert prog.source.endswith("m.cal")
    assert prog.formulation == "matrix"
