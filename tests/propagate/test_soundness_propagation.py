"""Soundness of propagation, property-based: no solution is ever lost.

Random expression trees over three unknowns use every operation of the language (+ - * /, unary
minus, integer powers, sqr sqrt exp log sin cos tan atan2 abs, and the two-output rotation). At
a random point each tree is evaluated in floats together with a rigorous bound on its rounding
error (`ev` below: first-order error propagation with Lipschitz bounds, checked against 80-digit
mpmath on 170k random trees while writing it, no violation). Each tree is then constrained to
an interval around its value that surely holds the exact real value, so the point is an exact
solution of the model; the unknowns get random boxes holding it. Propagation (hc4 and the tight
strategy) must then keep the point in every declared unknown, keep the exact value of every
intermediate in its slot, never report infeasibility, and never widen a domain.
"""

from __future__ import annotations

import math
import tempfile
import warnings
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib_dsl.compile.group import compile_model
from calib_dsl.elaborate.elaborator import elaborate
from calib_dsl.ir.dag import Dag
from calib_dsl.ir.model import Model
from calib_dsl.ir.program import Program
from calib_dsl.propagate.fixpoint import Result, propagate
from calib_dsl.strategy.tight import solve_tight

# -- floats with a rigorous error bound ---------------------------------------------------------

U = 2.0**-52  # >= 2 ulps relative: float64 operations and glibc's libm are within 1 ulp
ABS = 1e-300  # underflow to zero or into the subnormals
MAX = 1e100  # beyond, the point is not interesting (and a float may overflow)

Val = tuple[float, float]  # (v, e): the exact real value lies in [v - e, v + e]


def ev(op: str, args: list[Val], param: float | None = None) -> Val | None:
    """The float value of op(args) and a bound on its distance to the exact real value; None
    where the real value may be undefined (or lies out of the tested range)."""
    try:
        r = _ev(op, args, param)
    except (OverflowError, ValueError, ZeroDivisionError):
        return None
    if r is None:
        return None
    v, e = r
    v = v + 0.0  # a real number has no negative zero (atan2 would see the sign)
    if not (math.isfinite(v) and math.isfinite(e)) or abs(v) > MAX or e > MAX:
        return None
    return v, e + U * abs(v) + ABS


def _ev(op: str, a: list[Val], p: float | None) -> Val | None:
    x, ex = a[0]
    if op in ("add", "sub", "mul", "div"):
        y, ey = a[1]
        if op == "add":
            return x + y, ex + ey
        if op == "sub":
            return x - y, ex + ey
        if op == "mul":
            return x * y, abs(x) * ey + abs(y) * ex + ex * ey
        if abs(y) <= ey or y == 0:
            return None
        return x / y, (abs(x) * ey + abs(y) * ex) / (abs(y) * (abs(y) - ey))
    if op == "neg":
        return -x, ex
    if op == "abs":
        return abs(x), ex
    if op == "sqr":
        return x * x, 2 * abs(x) * ex + ex * ex
    if op == "pow":  # exponent >= 3 (0, 1, 2 and negative ones are rewritten before)
        n = int(p or 0)
        return x**n, n * (abs(x) + ex) ** (n - 1) * ex
    if op == "sqrt":
        if x - ex < 0:
            return None
        v = math.sqrt(x)
        return v, 0.0 if ex == 0 else ex / (math.sqrt(x - ex) + v)
    if op == "exp":
        if x + ex > 230:
            return None
        return math.exp(x), math.exp(x + ex) * ex
    if op == "log":
        if x - ex <= 0:
            return None
        return math.log(x), ex / (x - ex)
    if op == "sin":
        return math.sin(x), ex
    if op == "cos":
        return math.cos(x), ex
    if op == "tan":  # |tan'| = 1/cos^2, and |cos| >= |cos x| - ex on the error interval
        c = abs(math.cos(x)) - ex - 1e-15
        if c <= 1e-6:
            return None
        return math.tan(x), ex / (c * c)
    if op == "atan2":  # atan2(y, x): gradient norm 1/r, a jump of 2 pi across y = 0, x < 0
        (y, ey), (xx, exx) = a[0], a[1]
        y, d = y + 0.0, ey + exx  # -0.0 is the real 0: atan2(0, x < 0) = +pi
        if xx - exx < 0 and abs(y) <= ey and ey > 0:
            return None
        r = math.hypot(y, xx)
        if r - d <= 0:
            return None
        return math.atan2(y, xx), d / (r - d)
    if op in ("rotu", "rotv"):  # (u cos b - v sin b, u sin b + v cos b)
        (b, eb), (u, eu), (v, evv) = a
        c, s = math.cos(b), math.sin(b)
        val = u * c - v * s if op == "rotu" else u * s + v * c
        return val, (abs(u) + eu + abs(v) + evv) * eb + eu + evv + 4 * U * (abs(u) + abs(v))
    raise AssertionError(op)


def test_error_bounds_on_known_values():
    # exact operations have no error but the final margin; bounds grow with the inputs' errors
    v, e = ev("add", [(0.1, 0.0), (0.2, 0.0)])
    assert abs(v - 0.3) <= e < 1e-15
    assert ev("sqrt", [(-1e-20, 0.0)]) is None and ev("log", [(0.0, 0.0)]) is None
    assert ev("div", [(1.0, 0.0), (1e-3, 2e-3)]) is None
    assert ev("atan2", [(1e-9, 1e-8), (-1.0, 0.0)]) is None  # may be on either side of the cut
    v, e = ev("atan2", [(0.0, 0.0), (-1.0, 0.0)])
    assert abs(v - math.pi) <= e
    v, e = ev("atan2", [(-0.0, 0.0), (-2.0, 0.0)])
    assert v == math.atan2(0.0, -2.0)  # no negative zero: the real angle is +pi
    assert ev("tan", [(math.pi / 2, 0.0)]) is None
    v, e = ev("exp", [(1.0, 1e-10)])
    assert e >= math.e * 1e-10


# -- random expressions -------------------------------------------------------------------------

NVARS = 3
UNARY = ("neg", "sqr", "sqrt", "exp", "log", "sin", "cos", "tan", "abs")
BINARY = ("add", "sub", "mul", "div", "atan2")
CONSTS = (0.0, 0.5, 1.0, 2.0, 3.0, -1.0, -1.5, -2.0, 0.25, 10.0)


def expressions(rotations: bool) -> st.SearchStrategy:
    leaf = st.one_of(st.tuples(st.just("var"), st.integers(0, NVARS - 1)),
                     st.tuples(st.just("var"), st.integers(0, NVARS - 1)),
                     st.tuples(st.just("const"), st.sampled_from(CONSTS)))

    def extend(children: st.SearchStrategy) -> st.SearchStrategy:
        options = [st.tuples(st.sampled_from(UNARY), children),
                   st.tuples(st.sampled_from(BINARY), children, children),
                   st.tuples(st.just("pow"), st.integers(-3, 5), children)]
        if rotations:
            options.append(st.tuples(st.sampled_from(("rotu", "rotv")), children, children,
                                     children))
        return st.one_of(options)

    return st.recursive(leaf, extend, max_leaves=7)


def has_var(tree: tuple) -> bool:
    return tree[0] == "var" or any(isinstance(t, tuple) and has_var(t) for t in tree[1:])


POINTS = st.one_of(st.floats(-10, 10, allow_nan=False),
                   st.sampled_from([0.0, 1.0, -1.0, math.pi / 2, math.pi, 1e-8, -3.0, 0.5]))
WIDTHS = st.sampled_from([0.0, 1e-9, 1e-3, 0.5, 3.0, math.inf, math.inf])
# "shared": this tree AND the previous one are both constrained to the hull of their two
# intervals: one interval constant stated twice (membership, not identity: a regression test)
RELATIONS = st.sampled_from(["==", "==", "==", "<=", ">=", "both", "shared"])


def widen(v: float, e: float) -> tuple[float, float]:
    """An interval surely holding the real value: 4x the error bound and a relative 1e-9."""
    t = 4 * e + 1e-9 * abs(v)
    return v - t, v + t


def hull(a: tuple[float, float], b: tuple[float, float]) -> tuple[float, float]:
    return min(a[0], b[0]), max(a[1], b[1])


# -- the DAG built directly ------------------------------------------------------------------------

def build(dag: Dag, tree: tuple, leaves: list[tuple[int, Val]]) -> tuple[int, Val | None]:
    """The DAG node of `tree` and its value at the point (None where undefined)."""
    kind = tree[0]
    if kind == "var":
        return leaves[tree[1]]
    if kind == "const":
        return dag.const(tree[1]), (tree[1], 0.0)
    if kind == "pow":
        n, (node, val) = tree[1], build(dag, tree[2], leaves)
        pnode, pval = power(dag, node, val, abs(n))
        if n >= 0:
            return pnode, pval
        quotient = ev("div", [(1.0, 0.0), pval]) if pval is not None else None
        return dag.op("div", dag.const(1.0), pnode), quotient
    built = [build(dag, t, leaves) for t in tree[1:]]
    nodes = [b[0] for b in built]
    vals = [b[1] for b in built]
    value = None if any(v is None for v in vals) else ev(kind, vals)
    if kind in ("rotu", "rotv"):
        u, v = dag.rot(*nodes)
        return (u if kind == "rotu" else v), value
    return dag.op(kind, *nodes), value


def power(dag: Dag, node: int, val: Val | None, n: int) -> tuple[int, Val | None]:
    if n == 0:
        return dag.op("pow", node, data=0), (1.0, 0.0)
    out = dag.op("pow", node, data=n)
    if val is None:
        return out, None
    return out, val if n == 1 else ev("sqr", [val]) if n == 2 else ev("pow", [val], n)


def constrain(dag: Dag, node: int, val: Val, rel: str,
              prev: tuple[int, tuple[float, float]] | None) -> tuple[float, float]:
    lo, hi = widen(*val)
    if rel == "shared" and prev is not None:
        lo, hi = hull((lo, hi), prev[1])
        dag.constrain(prev[0], "==", dag.const(lo, hi))
        dag.constrain(node, "==", dag.const(lo, hi))
    if rel == "==" or (rel == "shared" and prev is None):
        dag.constrain(node, "==", dag.const(lo, hi))
    if rel in ("<=", "both"):
        dag.constrain(node, "<=", dag.const(hi))
    if rel in (">=", "both"):
        dag.constrain(dag.const(lo), "<=", node)
    return lo, hi


def check_sound(prog: Program, res: Result, point: dict[str, float], context: str) -> None:
    s = prog.slots
    assert res.status == "contracted", (context, res.emptied)
    # never widened, never emptied
    assert np.all(res.lo >= s.lo) and np.all(res.hi <= s.hi), context
    assert np.all(res.lo <= res.hi), context
    # the point is inside every declared unknown
    for name, slot in zip(s.declared_names, s.declared, strict=True):
        assert res.lo[slot] <= point[name] <= res.hi[slot], (context, name, point[name],
                                                             res.lo[slot], res.hi[slot])
    # and every intermediate's exact value (replayed through the primitives) is in its slot
    vals: dict[int, Val] = {slot: (point[name], 0.0)
                            for name, slot in zip(s.declared_names, s.declared, strict=True)}
    produced = {o for p in prog.primitives for o in p.out}
    for i, kind in enumerate(s.kinds):
        if kind == "const" and i not in produced and np.isfinite(s.hi[i] - s.lo[i]):
            lo, hi = float(s.lo[i]), float(s.hi[i])
            vals[i] = (0.5 * (lo + hi), 0.5 * (hi - lo) + 2 * math.ulp(max(-lo, hi)))
    for p in prog.primitives:
        if any(a not in vals for a in p.args):
            continue
        args = [vals[a] for a in p.args]
        outs = [ev("rotu", args), ev("rotv", args)] if p.op == "rot" else \
            [ev(p.op, args, p.param)]
        for slot, val in zip(p.out, outs, strict=True):
            if val is None:
                continue
            v, e = val
            assert res.lo[slot] <= v + 2 * e and v - 2 * e <= res.hi[slot], (
                context, s.names[slot], val, res.lo[slot], res.hi[slot])
            vals.setdefault(slot, val)


def make_model(trees, point, widths, relations) -> tuple[Program, dict[str, float]] | None:
    dag = Dag()
    names = [f"x{i}" for i in range(NVARS)]
    leaves = []
    for name, p, (wl, wh) in zip(names, point, widths, strict=True):
        leaves.append((dag.var(name, p - wl, p + wh, kind="var"), (p, 0.0)))
    prev = None
    for tree, rel in zip(trees, relations, strict=False):
        node, val = build(dag, tree, leaves)
        if val is None or dag.nodes[node].op == "const":
            continue  # undefined at the point, or folded to a constant
        prev = node, constrain(dag, node, val, rel, prev)
    if prev is None:
        return None
    return compile_model(Model("<hypothesis>", dag)), dict(zip(names, point, strict=True))


def quiet(fn, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return fn(*args, **kw)


CASES = dict(trees=st.lists(expressions(rotations=True), min_size=1, max_size=4),
             point=st.tuples(*[POINTS] * NVARS),
             widths=st.tuples(*[st.tuples(WIDTHS, WIDTHS)] * NVARS),
             relations=st.lists(RELATIONS, min_size=4, max_size=4),
             tol=st.sampled_from([0.0, 1e-5, 1e-2]))


# The suite runs each property on a share of its examples (quick enough for `make test-fast`);
# bench/checks/test_soundness_full.py runs each at its full count (the counts there).

@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(**CASES)
def test_propagation_keeps_the_point(trees, point, widths, relations, tol):
    made = make_model(trees, point, widths, relations)
    if made is None:
        return
    prog, at = made
    res = quiet(propagate, prog, tol=tol, max_sweeps=60)
    check_sound(prog, res, at, f"hc4 {trees}")


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(**CASES)
def test_tight_strategy_keeps_the_point(trees, point, widths, relations, tol):
    made = make_model(trees, point, widths, relations)
    if made is None:
        return
    prog, at = made
    res = quiet(solve_tight, prog, tol=tol, max_sweeps=60)
    check_sound(prog, res, at, f"tight {trees}")


BOXES = dict(trees=st.lists(expressions(rotations=True), min_size=1, max_size=3),
             point=st.tuples(*[POINTS] * NVARS),
             widths=st.tuples(*[st.tuples(WIDTHS, WIDTHS)] * NVARS),
             relations=st.lists(RELATIONS, min_size=3, max_size=3),
             box=st.data())


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(**BOXES)
def test_propagation_from_a_smaller_box(trees, point, widths, relations, box):
    """propagate(lo=, hi=): a box inside the declared domains that still holds the point."""
    made = make_model(trees, point, widths, relations)
    if made is None:
        return
    prog, at = made
    lo, hi = prog.slots.lo.copy(), prog.slots.hi.copy()
    for name, slot in zip(prog.slots.declared_names, prog.slots.declared, strict=True):
        p = at[name]
        lo[slot] = max(lo[slot], p - box.draw(WIDTHS))
        hi[slot] = min(hi[slot], p + box.draw(WIDTHS))
    res = quiet(propagate, prog, tol=0.0, max_sweeps=60, lo=lo, hi=hi)
    assert np.all(res.lo >= lo) and np.all(res.hi <= hi)
    check_sound(prog, res, at, f"box {trees}")


# Regression tests for a defect this file found (fixed since): each side of `expr == [lo, hi]`
# was unified with the hash-consed constant node [lo, hi], so two constraints against the same
# interval became expr1 == expr2.

def test_shared_interval_constant_found_by_hypothesis():
    # x0 = 0, x1 = -3, x2 = -1.11e-308: cos(x0) = 1 and exp(x1 x2) = 1 + 3.3e-308 are both in
    # [1 - 1e-9, 1 + 1e-9], but merged they force x1 x2 = 0: reported infeasible
    point = (0.0, -3.0, -1.1125369292536007e-308)
    dag = Dag()
    x = [dag.var(f"x{i}", p, p, kind="var") for i, p in enumerate(point)]
    one = dag.const(1 - 1e-9, 1 + 1e-9)
    dag.constrain(dag.op("cos", x[0]), "==", one)
    dag.constrain(dag.op("exp", dag.op("mul", x[1], x[2])), "==", one)
    prog = compile_model(Model("<shared>", dag))
    res = propagate(prog, tol=0.0)
    check_sound(prog, res, {f"x{i}": p for i, p in enumerate(point)}, "shared")


def test_shared_interval_constant_through_the_language(tmp_path):
    path = tmp_path / "s.cal"
    path.write_text("var x0 in [0, 0];\nvar x1 in [-3, -3];\nvar x2 in [-0.1, 0.2];\n"
                    "cos(x0) == [0.5, 1.5];\nexp(x1 * x2) == [0.5, 1.5];\n", encoding="utf-8")
    prog = compile_model(elaborate(path))
    res = propagate(prog, tol=0.0)
    # every x2 in [-0.1, 0.2] is a solution: exp(-3 x2) is in [0.54, 1.35]; merged with
    # cos(0) = 1 the propagator keeps x2 = 0 only
    x2 = prog.slots.declared[2]
    assert res.lo[x2] <= -0.1 and 0.2 <= res.hi[x2]


# -- the same through the .cal language (parser, elaborator, exact constant folding) ------------

def to_text(tree: tuple) -> str:
    kind = tree[0]
    if kind == "var":
        return f"x{tree[1]}"
    if kind == "const":
        return repr(tree[1])
    if kind == "pow":
        return f"({to_text(tree[2])})^({tree[1]})"
    args = [to_text(t) for t in tree[1:]]
    if kind in ("add", "sub", "mul", "div"):
        a, b = args
        return f"({a} {dict(add='+', sub='-', mul='*', div='/')[kind]} {b})"
    if kind == "neg":
        return f"(-{args[0]})"
    return f"{kind}({', '.join(args)})"


def bound(x: float) -> str:
    return "-oo" if x == -math.inf else "+oo" if x == math.inf else repr(x)


LANGUAGE = dict(trees=st.lists(expressions(rotations=False).filter(has_var), min_size=1,
                               max_size=3),
                point=st.tuples(*[POINTS] * NVARS),
                widths=st.tuples(*[st.tuples(WIDTHS, WIDTHS)] * NVARS),
                relations=st.lists(RELATIONS, min_size=3, max_size=3))


@settings(max_examples=30, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(**LANGUAGE)
def test_language_models_keep_the_point(trees, point, widths, relations):
    lines = [f"var x{i} in [{bound(p - wl)}, {bound(p + wh)}];"
             for i, (p, (wl, wh)) in enumerate(zip(point, widths, strict=True))]
    scratch = Dag()
    leaves = [(scratch.var(f"x{i}", -math.inf, math.inf), (p, 0.0)) for i, p in enumerate(point)]
    prev = None
    for tree, rel in zip(trees, relations, strict=False):
        val = build(scratch, tree, leaves)[1]
        if val is None:
            continue
        lo, hi = widen(*val)
        text = to_text(tree)
        if rel == "shared" and prev is not None:
            lo, hi = hull((lo, hi), prev[1])
            lines.append(f"{prev[0]} == [{bound(lo)}, {bound(hi)}];")
        if rel in ("==", "shared"):
            lines.append(f"{text} == [{bound(lo)}, {bound(hi)}];")
        prev = text, (lo, hi)
        if rel in ("<=", "both"):
            lines.append(f"{text} <= {bound(hi)};")
        if rel in (">=", "both"):
            lines.append(f"{bound(lo)} <= {text};")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "h.cal"
        path.write_text("\n".join(lines) + "\n", encoding="utf-8")
        prog = compile_model(elaborate(path))
    res = quiet(propagate, prog, tol=1e-5, max_sweeps=60)
    at = {f"x{i}": p for i, p in enumerate(point)}
    s = prog.slots
    assert res.status == "contracted", ("\n".join(lines), res.emptied)
    assert np.all(res.lo >= s.lo) and np.all(res.hi <= s.hi)
    for name, slot in zip(s.declared_names, s.declared, strict=True):
        assert res.lo[slot] <= at[name] <= res.hi[slot], ("\n".join(lines), name)
