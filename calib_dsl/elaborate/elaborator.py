"""Elaboration: a `.cal` model (AST) becomes the expression DAG, its unknowns and constraints.

Everything that can be computed at compile time is: loops are unrolled, macros and `let`
aliases expanded inline, indices resolved, robot chains built (by `robot.forward_point`),
measurement tables read. What remains is DAG nodes and `dag.constrain` calls.

Values during elaboration are
- `Fraction`: an exact compile-time number (literals, loop indices, `rows(m)`, and `+ - * / ^`
  on them), turned into an enclosing DAG constant only when it meets an unknown;
- `int`: a DAG node id (an unknown, a data cell, an interval constant, an operation);
- a tuple of those: a vector.
Names may also denote a family of unknowns, a macro, a robot or a table (the `Entity` types).
"""

from __future__ import annotations

import difflib
import itertools
import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any, Union

import numpy as np

from calib_dsl.elaborate import chains
from calib_dsl.elaborate.tables import cell_bounds, read_csv
from calib_dsl.frontend import ast
from calib_dsl.frontend.diagnostics import CalError, Loc
from calib_dsl.frontend.parser import parse_file
from calib_dsl.ir.dag import Dag
from calib_dsl.ir.model import Column, Model, Table

INF = math.inf
FORMULATIONS = ("matrix", "rotation")
# Built-in functions: name -> (number of arguments, DAG op).
FUNCTIONS = {"sqr": 1, "sqrt": 1, "exp": 1, "log": 1, "sin": 1, "cos": 1, "tan": 1, "abs": 1,
             "atan2": 2}
SPECIAL = {"rows": 1, "dot": 2}
BUILTINS = set(FUNCTIONS) | set(SPECIAL)
_ARITH = {"+": "add", "-": "sub", "*": "mul", "/": "div"}
_OP_NAMES = {"add": "the sum", "sub": "the difference", "mul": "the product",
             "div": "the quotient", "neg": "the opposite", "pow": "the power"}
MAX_POW_BITS = 1 << 16  # exact rational powers up to this size; beyond, interval arithmetic
MAX_UNROLL = 10_000_000  # loop iterations / family elements: a guard against typos

Scalar = Union[Fraction, int]  # noqa: UP007 - an alias used at run time too
Value = Union[Fraction, int, tuple[Scalar, ...]]  # noqa: UP007


# -- what names denote ------------------------------------------------------------------------
@dataclass(frozen=True)
class Family:
    """An indexed family of declared unknowns, possibly with its first indices given."""

    name: str
    dims: tuple[tuple[int, int], ...]  # (first, last) index of each dimension
    nodes: dict[tuple[int, ...], int]
    prefix: tuple[int, ...] = ()


@dataclass(frozen=True)
class Macro:
    name: str
    params: tuple[ast.Ident, ...]
    body: ast.Expr
    scope: Scope


@dataclass(frozen=True)
class RobotDef:
    name: str
    params: tuple[ast.Ident, ...]
    base: ast.FrameDecl | None
    joints: tuple[ast.FrameDecl, ...]
    scope: Scope


@dataclass(frozen=True)
class TableRef:
    name: str
    rows: int
    cells: dict[str, list[int]]  # column -> node of each row (row k at index k - 1)


@dataclass(frozen=True)
class ColumnRef:
    table: TableRef
    column: str


Entity = Union[Fraction, int, tuple, Family, Macro, RobotDef, TableRef, ColumnRef]  # noqa: UP007


class Scope:
    """Lexical scope: a name is defined once per scope; inner scopes may shadow outer names."""

    __slots__ = ("names", "parent")

    def __init__(self, parent: Scope | None = None) -> None:
        self.names: dict[str, tuple[Entity, Loc]] = {}
        self.parent = parent

    def lookup(self, name: str) -> tuple[Entity, Loc] | None:
        scope: Scope | None = self
        while scope is not None:
            hit = scope.names.get(name)
            if hit is not None:
                return hit
            scope = scope.parent
        return None

    def check_new(self, ident: ast.Ident) -> None:
        if ident.id in BUILTINS:
            raise CalError(f"'{ident.id}' is a built-in function: choose another name", ident.loc)
        old = self.names.get(ident.id)
        if old is not None:
            raise CalError(f"'{ident.id}' is already defined (at {old[1]})", ident.loc)

    def define(self, ident: ast.Ident, entity: Entity) -> None:
        self.check_new(ident)
        self.names[ident.id] = (entity, ident.loc)

    def visible(self) -> set[str]:
        out: set[str] = set()
        scope: Scope | None = self
        while scope is not None:
            out.update(scope.names)
            scope = scope.parent
        return out


# -- entry point ------------------------------------------------------------------------------
def elaborate(path: str | Path, *, formulation: str = "matrix", data: str | Path | None = None,
              simulate_rows: int | None = None) -> Model:
    """Elaborate the model file at `path` into a `Model` (DAG, unknowns, constraints, tables).

    `data` replaces the CSV file of the model's first table. `simulate_rows=N` is simulation
    mode: no CSV is read, each table has N rows, and each cell is a `data` variable of the DAG.
    """
    if formulation not in FORMULATIONS:
        raise CalError(f"unknown formulation '{formulation}' (expected matrix or rotation)")
    if simulate_rows is not None and simulate_rows < 1:
        raise CalError(f"simulation needs at least one row, not {simulate_rows}")
    run = _Elaborator(formulation, data, simulate_rows)
    try:
        run.file(str(path))
    except RecursionError:
        raise CalError("the model nests too deeply to elaborate", None) from None
    if data is not None and not run.tables:
        raise CalError(f"a data file ({data}) was given, but the model declares no table")
    return Model(path=str(path), dag=run.dag, tables=run.tables, formulation=formulation,
                 simulation=simulate_rows is not None)


class _Elaborator:
    def __init__(self, formulation: str, data: str | Path | None,
                 simulate_rows: int | None) -> None:
        self.dag = Dag()
        self.formulation = formulation
        self.data = data
        self.simulate_rows = simulate_rows
        self.tables: list[Table] = []
        self.globals = Scope()
        self.including: list[tuple[Path, str]] = []  # the include stack (resolved, as shown)
        self.included: set[Path] = set()
        self.expanding: list[Macro] = []
        self._consts: dict[Fraction, int] = {}
        # Robot uses are pure functions of their arguments: computed once each.
        self._robot_frames: dict[tuple, list[Any]] = {}
        self._robot_calls: dict[tuple, tuple[int, ...]] = {}
        self._stmts: dict[type, Callable[[Any, Scope, bool], None]] = {
            ast.Const: self._const, ast.Let: self._let, ast.Def: self._def,
            ast.Decl: self._decl, ast.For: self._for, ast.Include: self._include,
            ast.Constraint: self._constraint, ast.Robot: self._robot,
            ast.TableDecl: self._table,
        }
        self._exprs: dict[type, Callable[[Any, Scope], Entity]] = {
            ast.Number: lambda e, s: e.value, ast.Pi: lambda e, s: self.dag.pi(),
            ast.Infinity: self._infinity, ast.Name: self._name, ast.Neg: self._neg,
            ast.BinOp: self._binop, ast.Call: self._call, ast.RobotAt: self._robot_at,
            ast.Index: self._index, ast.Field: self._field, ast.TupleLit: self._tuple,
            ast.IntervalLit: self._interval,
        }

    # -- files and statements -------------------------------------------------------------
    def file(self, shown: str) -> None:
        resolved = Path(shown).resolve()
        self.including.append((resolved, shown))
        try:
            self.block(parse_file(shown), self.globals, top=True)
        finally:
            self.including.pop()
        self.included.add(resolved)

    def block(self, stmts: tuple[ast.Stmt, ...], scope: Scope, top: bool) -> None:
        for stmt in stmts:
            self._stmts[type(stmt)](stmt, scope, top)

    def _top_only(self, what: str, loc: Loc, top: bool) -> None:
        if not top:
            raise CalError(f"{what} is only allowed at the top level of a file, not inside "
                           "a loop", loc)

    def _const(self, s: ast.Const, scope: Scope, top: bool) -> None:
        value = self.value(s.value, scope)
        items = value if isinstance(value, tuple) else (value,)
        if not all(self._is_constant(x) for x in items):
            raise CalError(f"const '{s.name.id}' depends on unknowns: a const must be a "
                           "constant expression (use let for an alias)", s.value.loc)
        scope.define(s.name, value)

    def _let(self, s: ast.Let, scope: Scope, top: bool) -> None:
        scope.define(s.name, self.entity(s.value, scope))

    def _def(self, s: ast.Def, scope: Scope, top: bool) -> None:
        _check_params(s.params, "parameter")
        scope.define(s.name, Macro(s.name.id, s.params, s.body, scope))

    def _for(self, s: ast.For, scope: Scope, top: bool) -> None:
        lo = self.integer(s.range.lo, scope, "a loop bound")
        hi = self.integer(s.range.hi, scope, "a loop bound")
        if hi - lo >= MAX_UNROLL:
            raise CalError(f"loop of {hi - lo + 1} iterations: more than {MAX_UNROLL}", s.loc)
        for k in range(lo, hi + 1):
            inner = Scope(scope)
            inner.define(s.var, Fraction(k))
            self.block(s.body, inner, top=False)

    def _include(self, s: ast.Include, scope: Scope, top: bool) -> None:
        self._top_only("include", s.loc, top)
        shown = os.path.normpath(os.path.join(os.path.dirname(s.loc.file), s.path))
        if not Path(shown).is_file():
            raise CalError(f"include file '{s.path}' not found (looked for '{shown}')", s.loc)
        resolved = Path(shown).resolve()
        if any(resolved == r for r, _ in self.including):
            chain = " -> ".join([n for _, n in self.including] + [shown])
            raise CalError(f"include cycle: {chain}", s.loc)
        if resolved not in self.included:  # a file already included is not included again
            self.file(shown)

    def _constraint(self, s: ast.Constraint, scope: Scope, top: bool) -> None:
        if s.rel == "=":
            raise CalError("'=' defines a name (const, let, def); a constraint is stated "
                           "with '==', as in `lhs == rhs;`", s.rel_loc)
        if s.rel in ("<", ">"):
            raise CalError(f"strict inequality '{s.rel}' is not supported: over intervals it "
                           f"means the same as '{s.rel}=' - write that", s.rel_loc)
        lhs, rhs = self.value(s.lhs, scope), self.value(s.rhs, scope)
        for a, b in _pairs(lhs, rhs, "compare", s.rel_loc):
            self.dag.constrain(self.node(a, s.lhs.loc), s.rel, self.node(b, s.rhs.loc), s.loc)

    # -- declarations of unknowns ---------------------------------------------------------
    def _decl(self, s: ast.Decl, scope: Scope, top: bool) -> None:
        self._top_only(f"a {s.kind} declaration", s.loc, top)
        lo, hi, center = self.domain(s.domain, scope)
        true = center if s.true is None else self.true_value(s.true, scope)
        for dn in s.names:
            scope.check_new(dn.name)
            if dn.dims:
                scope.define(dn.name, self._family(s, dn, scope, (lo, hi), true))
            else:
                t = self._check_true(true, s, dn.name.id, lo, hi)
                node = self.dag.var(dn.name.id, lo, hi, dn.name.loc, kind=s.kind, true=t)
                scope.define(dn.name, node)

    def _family(self, s: ast.Decl, dn: ast.DeclName, scope: Scope, dom: tuple[float, float],
                true: float | tuple[float, ...] | None) -> Family:
        dims = tuple(self._dim(r, scope) for r in dn.dims)
        size = math.prod(b - a + 1 for a, b in dims)
        if size > MAX_UNROLL:
            raise CalError(f"family '{dn.name.id}' has {size} elements: more than {MAX_UNROLL}",
                           dn.name.loc)
        if isinstance(true, tuple) and (len(dims) != 1 or len(true) != size):
            raise CalError(f"{len(true)} true values for '{dn.name.id}', which has {size} "
                           "elements (a vector of true values fits a 1-D family)",
                           s.true.loc if s.true else s.loc)
        nodes = {}
        for n, idx in enumerate(itertools.product(*(range(a, b + 1) for a, b in dims))):
            name = dn.name.id + "".join(f"[{i}]" for i in idx)
            t = self._check_true(true[n] if isinstance(true, tuple) else true, s, name, *dom)
            nodes[idx] = self.dag.var(name, dom[0], dom[1], dn.name.loc, kind=s.kind, true=t)
        return Family(dn.name.id, dims, nodes)

    def _dim(self, r: ast.Range, scope: Scope) -> tuple[int, int]:
        lo = self.integer(r.lo, scope, "an index bound")
        hi = self.integer(r.hi, scope, "an index bound")
        if lo > hi:
            raise CalError(f"empty index range {lo}..{hi}", r.loc)
        return lo, hi

    def _check_true(self, true: float | tuple[float, ...] | None, s: ast.Decl, name: str,
                    lo: float, hi: float) -> float | None:
        loc = s.true.loc if s.true is not None else s.loc
        if isinstance(true, tuple):
            raise CalError(f"'{name}' is a scalar: its true value is a number, not a vector", loc)
        if true is not None and not lo <= true <= hi:
            raise CalError(f"true value {true!r} of '{name}' is outside its domain "
                           f"[{lo!r}, {hi!r}]", loc)
        return true

    def domain(self, e: ast.Expr | None, scope: Scope) -> tuple[float, float, float | None]:
        """(lo, hi, default true value) of a domain: `[a, b]`, `c +- t`, or a constant."""
        if e is None:
            return -INF, INF, None
        if isinstance(e, ast.IntervalLit):
            lo, hi = self._bounds(e, scope)
            return lo, hi, None
        v = self.value(e, scope)
        lo, hi = self.constant_interval(v, e.loc, "a domain")
        center = None
        if isinstance(e, ast.BinOp) and e.op == "+-":
            center = self._point(e.left, scope, "the center of '+-'")
        elif isinstance(v, Fraction):
            center = _nearest(v, e.loc)
        elif lo == hi:
            center = lo
        return lo, hi, center

    def true_value(self, e: ast.Expr, scope: Scope) -> float | tuple[float, ...]:
        if isinstance(e, ast.TupleLit):
            return tuple(self._point(x, scope, "a true value") for x in e.items)
        return self._point(e, scope, "a true value")

    def _point(self, e: ast.Expr, scope: Scope, what: str) -> float:
        """A constant as one float (an interval constant gives its midpoint)."""
        if isinstance(e, ast.IntervalLit) or (isinstance(e, ast.BinOp) and e.op == "+-"):
            raise CalError(f"{what} must be a number, not an interval", e.loc)
        v = self.value(e, scope)
        if isinstance(v, Fraction):
            return _nearest(v, e.loc)
        lo, hi = self.constant_interval(v, e.loc, what)
        if not (math.isfinite(lo) and math.isfinite(hi)):
            raise CalError(f"{what} must be finite", e.loc)
        mid = lo if lo == hi else 0.5 * lo + 0.5 * hi
        if hi - lo > 1e-9 * max(1.0, abs(mid)):  # wider than rounding: a real interval
            raise CalError(f"{what} must be a number, not an interval [{lo!r}, {hi!r}]", e.loc)
        return mid

    # -- robots ---------------------------------------------------------------------------
    def _robot(self, s: ast.Robot, scope: Scope, top: bool) -> None:
        self._top_only("a robot definition", s.loc, top)
        _check_params(s.params, "joint variable")
        base = None
        joints = []
        for i, frame in enumerate(s.frames):
            allowed = ("theta", "r") if frame.kind == "base" else ("alpha", "d", "theta", "r")
            _check_entries(frame, allowed)
            if frame.kind == "base":
                if i != 0:
                    raise CalError("the base frame must come first, and only once", frame.loc)
                base = frame
            else:
                joints.append(frame)
        if not joints:
            raise CalError(f"robot '{s.name.id}' has no joint", s.loc)
        scope.define(s.name, RobotDef(s.name.id, s.params, base, tuple(joints), scope))

    def _robot_at(self, e: ast.RobotAt, scope: Scope) -> tuple[int, ...]:
        robot = self._lookup(e.robot, e.loc, scope)
        if not isinstance(robot, RobotDef):
            raise CalError(f"'{e.robot}' is not a robot: 'at' gives the workshop coordinates "
                           "of a tool point on a robot", e.loc)
        if len(e.args) != len(robot.params):
            raise CalError(f"robot '{e.robot}' takes {_count(len(robot.params), 'joint value')}"
                           f", got {len(e.args)}", e.loc)
        args = tuple(self.scalar(self.value(a, scope), a.loc, "a joint value") for a in e.args)
        point = self.value(e.point, scope)
        if not isinstance(point, tuple) or len(point) != 3:
            raise CalError(f"a tool point is a 3-vector (x, y, z), not {_kind(point)}",
                           e.point.loc)
        where = e.point.loc
        xyz = (self.node(point[0], where), self.node(point[1], where), self.node(point[2], where))
        key = (id(robot), args, xyz)
        found = self._robot_calls.get(key)
        if found is None:
            frames = self._frames(robot, args)
            found = tuple(chains.forward_point(self.dag, frames, xyz, self.formulation))
            self._robot_calls[key] = found
        return found

    def _frames(self, robot: RobotDef, args: tuple[Scalar, ...]) -> list[Any]:
        """The frames of a robot for these joint values (the same for every tool point)."""
        key = (id(robot), args)
        frames = self._robot_frames.get(key)
        if frames is None:
            inner = Scope(robot.scope)
            for p, a in zip(robot.params, args, strict=True):
                inner.names[p.id] = (a, p.loc)
            frames = [self._frame(robot.base, inner)]
            frames += [self._frame(j, inner) for j in robot.joints]
            self._robot_frames[key] = frames
        return frames

    def _frame(self, decl: ast.FrameDecl | None, scope: Scope) -> Any:
        values = {}
        for entry in decl.entries if decl is not None else ():
            v = self.scalar(self.value(entry.value, scope), entry.value.loc, "a frame entry")
            values[entry.name.id] = self.node(v, entry.value.loc)
        zero = self.dag.const(0.0)
        return chains.Frame(alpha=values.get("alpha", zero), d=values.get("d", zero),
                           theta=values.get("theta", zero), r=values.get("r", zero))

    # -- tables ---------------------------------------------------------------------------
    def _table(self, s: ast.TableDecl, scope: Scope, top: bool) -> None:
        self._top_only("a table declaration", s.loc, top)
        scope.check_new(s.name)
        columns, locs = self._columns(s, scope)
        first = not self.tables
        if first and self.data is not None:
            path = str(self.data)
        else:
            path = os.path.normpath(os.path.join(os.path.dirname(s.loc.file), s.path))
        if self.simulate_rows is not None:
            rows = self.simulate_rows
            cells = {c.name: [self.dag.var(f"{s.name.id}.{c.name}[{k}]", -INF, INF,
                                           locs[c.name], kind="data")
                              for k in range(1, rows + 1)] for c in columns}
        else:
            data = read_csv(path, [c.name for c in columns],
                            None if first and self.data is not None else s.path_loc)
            rows = data.rows
            cells = {}
            for c in columns:
                lo, hi = cell_bounds(*data.enclosures[c.name], c.tol)
                cells[c.name] = [self.dag.cell(a, b, s.name.id, c.name, k)
                                 for k, (a, b) in enumerate(zip(lo.tolist(), hi.tolist(),
                                                                strict=True), start=1)]
        self.tables.append(Table(s.name.id, path, columns, rows, s.loc))
        scope.define(s.name, TableRef(s.name.id, rows, cells))

    def _columns(self, s: ast.TableDecl, scope: Scope) -> tuple[list[Column], dict[str, Loc]]:
        columns: list[Column] = []
        locs: dict[str, Loc] = {}
        for g in s.groups:
            tol = self._tolerance(g.tol, scope)
            sim = None
            if g.simulate is not None:
                lo, hi, _ = self.domain(g.simulate, scope)
                if not (math.isfinite(lo) and math.isfinite(hi)):
                    raise CalError("a simulation range must be finite (values are drawn "
                                   "uniformly in it)", g.simulate.loc)
                sim = (lo, hi)
            for ident in g.names:
                if ident.id in locs:
                    raise CalError(f"column '{ident.id}' is already declared (at "
                                   f"{locs[ident.id]})", ident.loc)
                locs[ident.id] = ident.loc
                columns.append(Column(ident.id, tol, sim))
        if not columns:
            raise CalError(f"table '{s.name.id}' declares no column", s.loc)
        return columns, locs

    def _tolerance(self, e: ast.Expr, scope: Scope) -> float:
        lo, hi = self.constant_interval(self.value(e, scope), e.loc, "a tolerance")
        if lo < 0:
            raise CalError(f"a tolerance must be >= 0, not {lo!r}", e.loc)
        if not math.isfinite(hi):
            raise CalError("a tolerance must be finite", e.loc)
        return hi

    # -- expressions ----------------------------------------------------------------------
    def entity(self, e: ast.Expr, scope: Scope) -> Entity:
        """What an expression denotes (a value, or a family/macro/robot/table/column)."""
        return self._exprs[type(e)](e, scope)

    def value(self, e: ast.Expr, scope: Scope) -> Value:
        """The value of an expression: a number, a DAG node, or a vector."""
        ent = self._exprs[type(e)](e, scope)
        kind = type(ent)
        if kind is int or kind is Fraction or kind is tuple:  # (faster than isinstance)
            return ent  # type: ignore[return-value]
        return self._as_value(ent, e.loc)

    def _as_value(self, ent: Entity, loc: Loc) -> Value:
        if isinstance(ent, Family):
            done = len(ent.prefix)
            if len(ent.dims) - done == 1:
                first, last = ent.dims[done]
                return tuple(ent.nodes[ent.prefix + (i,)] for i in range(first, last + 1))
            raise CalError(f"'{ent.name}' has {len(ent.dims)} indices: give "
                           f"{len(ent.dims) - done - 1} more to use it as a value", loc)
        if isinstance(ent, Macro):
            raise CalError(f"'{ent.name}' is a macro: call it, {ent.name}(...)", loc)
        if isinstance(ent, RobotDef):
            raise CalError(f"'{ent.name}' is a robot: use it as {ent.name}(joint values) at "
                           "(x, y, z)", loc)
        if isinstance(ent, TableRef):
            raise CalError(f"'{ent.name}' is a table: use a cell, {ent.name}.column[row], or "
                           f"rows({ent.name})", loc)
        if isinstance(ent, ColumnRef):
            raise CalError(f"'{ent.table.name}.{ent.column}' is a column: give a row, "
                           f"{ent.table.name}.{ent.column}[k]", loc)
        return ent  # type: ignore[return-value]

    def _lookup(self, name: str, loc: Loc, scope: Scope) -> Entity:
        hit = scope.lookup(name)
        if hit is not None:
            return hit[0]
        if name in BUILTINS:
            raise CalError(f"'{name}' is a built-in function: call it, {name}(...)", loc)
        near = difflib.get_close_matches(name, scope.visible(), n=1)
        hint = f" (did you mean '{near[0]}'?)" if near else ""
        raise CalError(f"unknown name '{name}'{hint}", loc)

    def _name(self, e: ast.Name, scope: Scope) -> Entity:
        return self._lookup(e.id, e.loc, scope)

    def _infinity(self, e: ast.Infinity, scope: Scope) -> Entity:
        raise CalError("'oo' (infinity) can only be a bound of an interval, as in [0, +oo]",
                       e.loc)

    def _neg(self, e: ast.Neg, scope: Scope) -> Value:
        v = self.value(e.arg, scope)
        if isinstance(v, tuple):
            return tuple(self._negate(x, e.loc) for x in v)
        return self._negate(v, e.loc)

    def _negate(self, v: Scalar, loc: Loc) -> Scalar:
        return -v if isinstance(v, Fraction) else self._op("neg", (v,), loc)

    def _binop(self, e: ast.BinOp, scope: Scope) -> Value:
        if e.op == "^":
            return self._power(e, scope)
        a, b = self.value(e.left, scope), self.value(e.right, scope)
        if e.op == "+-":
            return self._plusminus(a, b, e)
        if isinstance(a, tuple) or isinstance(b, tuple):
            return self._vector_arith(e.op, a, b, e.loc)
        return self.arith(e.op, a, b, e.loc)

    def arith(self, op: str, a: Scalar, b: Scalar, loc: Loc) -> Scalar:
        if isinstance(a, Fraction) and isinstance(b, Fraction):
            if op == "/" and b == 0:
                raise CalError("division by zero", loc)
            if op == "+":
                return a + b
            if op == "-":
                return a - b
            return a * b if op == "*" else a / b
        # x*x is sqr(x), a tighter contractor; both must be DAG nodes (ints), not an exact
        # constant that happens to equal a node id (Fraction(1) == 1)
        if op == "*" and type(a) is int and type(b) is int and a == b:
            return self._op("sqr", (a,), loc)
        return self._op(_ARITH[op], (self.node(a, loc), self.node(b, loc)), loc)

    def _vector_arith(self, op: str, a: Value, b: Value, loc: Loc) -> Value:
        if op in "+-":
            return tuple(self.arith(op, x, y, loc) for x, y in _pairs(a, b, "add", loc))
        if op == "*" and isinstance(a, tuple) and isinstance(b, tuple):
            raise CalError("'*' between two vectors: use dot(u, v) for the dot product", loc)
        if op == "*" and isinstance(a, tuple):
            a, b = b, a
        if isinstance(b, tuple) and not isinstance(a, tuple) and op == "*":
            return tuple(self.arith("*", a, y, loc) for y in b)
        if op == "/" and isinstance(a, tuple) and not isinstance(b, tuple):
            return tuple(self.arith("/", x, b, loc) for x in a)
        raise CalError(f"cannot compute {_kind(a)} {op} {_kind(b)}", loc)

    def _power(self, e: ast.BinOp, scope: Scope) -> Value:
        base = self.value(e.left, scope)
        n = self.integer(e.right, scope, "an exponent",
                         hint=" (for a real power y, write exp(y * log(x)))")
        if isinstance(base, tuple):
            raise CalError(f"cannot raise {_kind(base)} to a power", e.loc)
        if isinstance(base, Fraction):
            if base == 0 and n < 0:
                raise CalError("division by zero (0 to a negative power)", e.loc)
            bits = max(base.numerator.bit_length(), base.denominator.bit_length())
            if bits * abs(n) <= MAX_POW_BITS or base in (0, 1, -1):
                return base ** n  # type: ignore[no-any-return]
        if n == 0:
            return Fraction(1)
        x = self.node(base, e.loc)
        if n > 0:
            return self._op("pow", (x,), e.loc, data=n)
        return self._op("div", (self.node(Fraction(1), e.loc),
                                self._op("pow", (x,), e.loc, data=-n)), e.loc)

    def _plusminus(self, c: Value, t: Value, e: ast.BinOp) -> Scalar:
        """`c +- t`: the constant interval [c - t, c + t]."""
        if isinstance(c, Fraction) and isinstance(t, Fraction):
            if t < 0:
                raise CalError(f"negative tolerance in '+-': {t}", e.right.loc)
            if t == 0:
                return c
            return self.dag.const(_enclose(c - t, e.loc)[0], _enclose(c + t, e.loc)[1],
                                  unique=True)
        clo, chi = self.constant_interval(c, e.left.loc, "the center of '+-'")
        tlo, thi = self.constant_interval(t, e.right.loc, "the tolerance of '+-'")
        if tlo < 0:
            raise CalError(f"negative tolerance in '+-': {tlo!r}", e.right.loc)
        if not math.isfinite(thi):
            raise CalError("the tolerance of '+-' must be finite", e.right.loc)
        return self.dag.const(float(np.nextafter(clo - thi, -INF)),
                              float(np.nextafter(chi + thi, INF)), unique=True)

    def _interval(self, e: ast.IntervalLit, scope: Scope) -> Scalar:
        lo, hi = self._bounds(e, scope)
        return self.dag.const(lo, hi, unique=True)

    def _bounds(self, e: ast.IntervalLit, scope: Scope) -> tuple[float, float]:
        """The floats enclosing [lo, hi] (bounds may be infinite); empty is an error."""
        lo, exact_lo = self._bound(e.lo, scope, lower=True)
        hi, exact_hi = self._bound(e.hi, scope, lower=False)
        empty = lo > hi if exact_lo is None or exact_hi is None else exact_lo > exact_hi
        if empty or lo == INF or hi == -INF:
            raise CalError(f"empty interval: lower bound {_show(exact_lo, lo)} is above upper "
                           f"bound {_show(exact_hi, hi)}" if empty else
                           "an interval must hold a real number, not only an infinity", e.loc)
        return lo, hi

    def _bound(self, e: ast.Expr, scope: Scope, lower: bool) -> tuple[float, Fraction | None]:
        sign, inner = 1, e
        while isinstance(inner, ast.Neg):
            sign, inner = -sign, inner.arg
        if isinstance(inner, ast.Infinity):
            return sign * INF, None
        v = self.value(e, scope)
        lo, hi = self.constant_interval(v, e.loc, "an interval bound")
        return (lo if lower else hi), (v if isinstance(v, Fraction) else None)

    def _tuple(self, e: ast.TupleLit, scope: Scope) -> tuple[Scalar, ...]:
        items = []
        for item in e.items:
            v = self.value(item, scope)
            if isinstance(v, tuple):
                raise CalError("vectors cannot be nested", item.loc)
            items.append(v)
        return tuple(items)

    # -- indices and tables ---------------------------------------------------------------
    def _index(self, e: ast.Index, scope: Scope) -> Entity:
        base = self.entity(e.base, scope)
        i = self.integer(e.index, scope, "an index")
        if isinstance(base, Family):
            first, last = base.dims[len(base.prefix)]
            if not first <= i <= last:
                raise CalError(f"index {i} out of range {first}..{last} of '{base.name}'",
                               e.index.loc)
            idx = base.prefix + (i,)
            if len(idx) == len(base.dims):
                return base.nodes[idx]
            return Family(base.name, base.dims, base.nodes, idx)
        if isinstance(base, ColumnRef):
            if not 1 <= i <= base.table.rows:
                raise CalError(f"row {i} out of range 1..{base.table.rows} of table "
                               f"'{base.table.name}'", e.index.loc)
            return base.table.cells[base.column][i - 1]
        value = self._as_value(base, e.base.loc)
        if not isinstance(value, tuple):
            raise CalError(f"cannot index {_kind(value)}", e.loc)
        if not 1 <= i <= len(value):
            raise CalError(f"index {i} out of range 1..{len(value)} of a {len(value)}-vector",
                           e.index.loc)
        return value[i - 1]

    def _field(self, e: ast.Field, scope: Scope) -> Entity:
        table = self.entity(e.base, scope)
        if not isinstance(table, TableRef):
            raise CalError("'.' selects a column of a table (table.column[row]), and this is "
                           "not a table", e.base.loc)
        if e.name not in table.cells:
            have = ", ".join(table.cells)
            raise CalError(f"table '{table.name}' has no column '{e.name}' (its columns: "
                           f"{have})", e.loc)
        return ColumnRef(table, e.name)

    # -- calls ----------------------------------------------------------------------------
    def _call(self, e: ast.Call, scope: Scope) -> Value:
        if e.func in FUNCTIONS:
            _arity(e, FUNCTIONS[e.func], "function")
            args = [self.scalar(self.value(a, scope), a.loc, f"an argument of {e.func}")
                    for a in e.args]
            return self.function(e.func, args, e.loc)
        if e.func == "rows":
            _arity(e, 1, "function")
            table = self.entity(e.args[0], scope)
            if not isinstance(table, TableRef):
                raise CalError("rows(t) takes a table", e.args[0].loc)
            return Fraction(table.rows)
        if e.func == "dot":
            _arity(e, 2, "function")
            return self._dot(self.value(e.args[0], scope), self.value(e.args[1], scope), e.loc)
        macro = self._lookup(e.func, e.loc, scope)
        if isinstance(macro, RobotDef):
            raise CalError(f"robot '{e.func}' gives the coordinates of a tool point: write "
                           f"{e.func}(joint values) at (x, y, z)", e.loc)
        if not isinstance(macro, Macro):
            raise CalError(f"'{e.func}' is not a function or macro", e.loc)
        return self._expand(macro, e, scope)

    def function(self, name: str, args: list[Scalar], loc: Loc) -> Scalar:
        x = args[0]
        if isinstance(x, Fraction) and name in ("sqr", "abs"):
            return x * x if name == "sqr" else abs(x)
        return self._op(name, tuple(self.node(a, loc) for a in args), loc)

    def _dot(self, u: Value, v: Value, loc: Loc) -> Scalar:
        if not (isinstance(u, tuple) and isinstance(v, tuple)):
            raise CalError(f"dot(u, v) takes two vectors, not {_kind(u)} and {_kind(v)}", loc)
        total: Scalar = Fraction(0)
        for x, y in _pairs(u, v, "multiply", loc):
            total = self.arith("+", total, self.arith("*", x, y, loc), loc)
        return total

    def _expand(self, macro: Macro, e: ast.Call, scope: Scope) -> Value:
        if len(e.args) != len(macro.params):
            raise CalError(f"macro '{macro.name}' takes {_count(len(macro.params), 'argument')}"
                           f", got {len(e.args)}", e.loc)
        if any(m is macro for m in self.expanding):
            chain = " -> ".join([m.name for m in self.expanding] + [macro.name])
            raise CalError(f"macro '{macro.name}' calls itself ({chain}): macros are expanded "
                           "inline, so recursion is not allowed", e.loc)
        inner = Scope(macro.scope)
        for p, a in zip(macro.params, e.args, strict=True):
            inner.names[p.id] = (self.entity(a, scope), p.loc)
        self.expanding.append(macro)
        try:
            return self.value(macro.body, inner)
        finally:
            self.expanding.pop()

    # -- conversions ----------------------------------------------------------------------
    def node(self, v: Scalar, loc: Loc) -> int:
        """The DAG node of a scalar (an exact number becomes its enclosing constant)."""
        if type(v) is int:
            return v
        assert isinstance(v, Fraction)
        found = self._consts.get(v)
        if found is None:
            found = self._consts[v] = self.dag.const(*_enclose(v, loc))
        return found

    def scalar(self, v: Value, loc: Loc, what: str) -> Scalar:
        if isinstance(v, tuple):
            raise CalError(f"{what} must be a number, not {_kind(v)}", loc)
        return v

    def _is_constant(self, v: Scalar) -> bool:
        return isinstance(v, Fraction) or self.dag.nodes[v].op == "const"

    def constant_interval(self, v: Value, loc: Loc, what: str) -> tuple[float, float]:
        if isinstance(v, tuple):
            raise CalError(f"{what} must be a number, not {_kind(v)}", loc)
        if isinstance(v, Fraction):
            return _enclose(v, loc)
        node = self.dag.nodes[v]
        if node.op != "const":
            raise CalError(f"{what} must be a constant; this depends on unknowns", loc)
        return node.data[0], node.data[1]  # type: ignore[no-any-return]

    def integer(self, e: ast.Expr, scope: Scope, what: str, hint: str = "") -> int:
        """A constant integer expression (loop bounds, indices, exponents)."""
        v = self.value(e, scope)
        if isinstance(v, Fraction) and v.denominator == 1:
            return int(v)
        if isinstance(v, int) and self.dag.nodes[v].op == "const":
            lo, hi = self.dag.nodes[v].data[:2]
            if lo == hi and float(lo).is_integer():
                return int(lo)
        shown = str(v) if isinstance(v, Fraction) else None
        if shown is None and isinstance(v, int) and self.dag.nodes[v].op != "const":
            raise CalError(f"{what} must be a constant integer; this depends on unknowns"
                           + hint, e.loc)
        raise CalError(f"{what} must be an integer" + (f", not {shown}" if shown else "")
                       + hint, e.loc)

    def _op(self, op: str, args: tuple[int, ...], loc: Loc, data: int | None = None) -> int:
        """`dag.op`, with a constant folded to an empty or undefined value a user error."""
        try:
            n = self.dag.op(op, *args, data=data)
        except (ArithmeticError, ValueError) as err:
            raise CalError(f"cannot compute {_OP_NAMES.get(op, op)} of these constants ({err})",
                           loc) from None
        node = self.dag.nodes[n]
        if node.op == "const" and not node.data[0] <= node.data[1]:
            raise CalError(f"{_OP_NAMES.get(op, op)} of these constants has no value (an "
                           "argument is outside the function's domain)", loc)
        return n


# -- helpers ----------------------------------------------------------------------------------
def _enclose(q: Fraction, loc: Loc | None) -> tuple[float, float]:
    """The tightest float interval holding the exact rational q."""
    x = _nearest(q, loc)
    exact = Fraction(x)
    if exact == q:
        return x, x
    if exact < q:
        return x, float(np.nextafter(x, INF))
    return float(np.nextafter(x, -INF)), x


def _nearest(q: Fraction, loc: Loc | None) -> float:
    try:
        return q.numerator / q.denominator  # correctly rounded
    except OverflowError:
        raise CalError("number too large for a float", loc) from None


def _pairs(a: Value, b: Value, verb: str, loc: Loc) -> list[tuple[Scalar, Scalar]]:
    """Scalar with scalar, or vectors of equal length element by element."""
    if isinstance(a, tuple) and isinstance(b, tuple):
        if len(a) != len(b):
            raise CalError(f"cannot {verb} a {len(a)}-vector and a {len(b)}-vector", loc)
        return list(zip(a, b, strict=True))
    if isinstance(a, tuple) or isinstance(b, tuple):
        raise CalError(f"cannot {verb} {_kind(a)} and {_kind(b)}", loc)
    return [(a, b)]


def _kind(v: Value) -> str:
    return f"a {len(v)}-vector" if isinstance(v, tuple) else "a number"


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" + ("" if n == 1 else "s")


def _show(exact: Fraction | None, x: float) -> str:
    return str(exact) if exact is not None else repr(x)


def _arity(e: ast.Call, n: int, what: str) -> None:
    if len(e.args) != n:
        raise CalError(f"{what} '{e.func}' takes {_count(n, 'argument')}, got {len(e.args)}",
                       e.loc)


def _check_params(idents: tuple[ast.Ident, ...], what: str) -> None:
    seen: dict[str, Loc] = {}
    for i in idents:
        if i.id in BUILTINS:
            raise CalError(f"'{i.id}' is a built-in function: choose another name", i.loc)
        if i.id in seen:
            raise CalError(f"duplicate {what} '{i.id}' (first at {seen[i.id]})", i.loc)
        seen[i.id] = i.loc


def _check_entries(frame: ast.FrameDecl, allowed: tuple[str, ...]) -> None:
    seen: set[str] = set()
    for entry in frame.entries:
        name = entry.name.id
        if name not in allowed:
            extra = " (the base frame has alpha = d = 0)" if frame.kind == "base" else ""
            raise CalError(f"a {frame.kind} frame has entries {', '.join(allowed)}, not "
                           f"'{name}'{extra}", entry.name.loc)
        if name in seen:
            raise CalError(f"entry '{name}' given twice", entry.name.loc)
        seen.add(name)
