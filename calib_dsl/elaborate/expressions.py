"""Expressions: names, arithmetic, powers, +-, intervals, vectors, indices, fields, calls
and macros, evaluated exactly where they are constant and as DAG nodes where not.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Callable
from fractions import Fraction

import numpy as np

from calib_dsl.elaborate import chains
from calib_dsl.elaborate.checks import (
    ARITH_OPS,
    INF,
    MAX_POW_BITS,
    OP_NAMES,
    check_arity,
    count,
    enclose,
    kind_of,
    pairs,
    show,
)
from calib_dsl.elaborate.context import Context
from calib_dsl.elaborate.scope import (
    BUILTINS,
    FUNCTIONS,
    SPECIAL,
    ColumnRef,
    Entity,
    Family,
    Macro,
    RobotDef,
    Scalar,
    Scope,
    TableRef,
    Value,
)
from calib_dsl.frontend import ast
from calib_dsl.frontend.diagnostics import CalError, Loc

CHAINED = ("+", "-", "*", "/")  # left-associative: long chains are walked, not recursed


class Expressions(Context):
    """Expressions to values (exact numbers, DAG nodes, vectors) or entities."""

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

    def lookup(self, name: str, loc: Loc, scope: Scope) -> Entity:
        hit = scope.lookup(name)
        if hit is not None:
            if self.is_global_const(name, hit):
                self.const_reads[name] = self.const_reads.get(name, 0) + 1
            return hit[0]
        if name in BUILTINS:
            raise CalError(f"'{name}' is a built-in function: call it, {name}(...)", loc)
        near = difflib.get_close_matches(name, scope.visible(), n=1)
        hint = f" (did you mean '{near[0]}'?)" if near else ""
        raise CalError(f"unknown name '{name}'{hint}", loc)

    def is_global_const(self, name: str, hit: tuple[Entity, Loc] | None) -> bool:
        """Whether `hit` (a scope's entry for `name`) is a top-level numeric const."""
        return name in self.const_values and hit is not None \
            and hit is self.globals.names.get(name)

    def _name(self, e: ast.Name, scope: Scope) -> Entity:
        return self.lookup(e.id, e.loc, scope)

    def _infinity(self, e: ast.Infinity, scope: Scope) -> Entity:
        raise CalError("'oo' (infinity) can only be a bound of an interval, as in [0, +oo]",
                       e.loc)

    def _neg(self, e: ast.Neg, scope: Scope) -> Value:
        v = self.value(e.arg, scope)
        if isinstance(v, tuple):
            return tuple(self._negate(x, e.loc) for x in v)
        return self._negate(v, e.loc)

    def _negate(self, v: Scalar, loc: Loc) -> Scalar:
        if isinstance(v, Fraction):
            return -v
        out = self._op("neg", (v,), loc)
        if v in self.dag.cells and self.dag.point(v) is not None:
            self.negated_cells[out] = v  # an exact cell, negated (folded): still that cell
        return out

    def _binop(self, e: ast.BinOp, scope: Scope) -> Value:
        if e.op == "^":
            return self._power(e, scope)
        if e.op in CHAINED and isinstance(e.left, ast.BinOp) and e.left.op in CHAINED:
            return self._chain(e, scope)
        a, b = self.value(e.left, scope), self.value(e.right, scope)
        if e.op == "+-":
            return self._plusminus(a, b, e)
        return self._combine(e, a, b)

    def _combine(self, e: ast.BinOp, a: Value, b: Value) -> Value:
        if isinstance(a, tuple) or isinstance(b, tuple):
            return self._vector_arith(e.op, a, b, e.loc)
        return self.arith(e.op, a, b, e.loc)

    def _chain(self, e: ast.BinOp, scope: Scope) -> Value:
        """a + b - c + ...: the parser's left-deep tree walked down its spine, not recursed
        into (a sum of thousands of terms is flat, not nested)."""
        spine = []
        node: ast.Expr = e
        while isinstance(node, ast.BinOp) and node.op in CHAINED:
            spine.append(node)
            node = node.left
        acc = self.value(node, scope)
        for op in reversed(spine):
            acc = self._combine(op, acc, self.value(op.right, scope))
        return acc

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
        return self._op(ARITH_OPS[op], (self.node(a, loc), self.node(b, loc)), loc)

    def _vector_arith(self, op: str, a: Value, b: Value, loc: Loc) -> Value:
        if op in "+-":
            return tuple(self.arith(op, x, y, loc) for x, y in pairs(a, b, "add", loc))
        if op == "*" and isinstance(a, tuple) and isinstance(b, tuple):
            raise CalError("'*' between two vectors: use dot(u, v) for the dot product", loc)
        if op == "*" and isinstance(a, tuple):
            a, b = b, a
        if isinstance(b, tuple) and not isinstance(a, tuple) and op == "*":
            return tuple(self.arith("*", a, y, loc) for y in b)
        if op == "/" and isinstance(a, tuple) and not isinstance(b, tuple):
            return tuple(self.arith("/", x, b, loc) for x in a)
        raise CalError(f"cannot compute {kind_of(a)} {op} {kind_of(b)}", loc)

    def _power(self, e: ast.BinOp, scope: Scope) -> Value:
        base = self.value(e.left, scope)
        n = self.integer(e.right, scope, "an exponent",
                         hint=" (for a real power y, write exp(y * log(x)))")
        if isinstance(base, tuple):
            raise CalError(f"cannot raise {kind_of(base)} to a power", e.loc)
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
            return self.dag.const(enclose(c - t, e.loc)[0], enclose(c + t, e.loc)[1],
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
        lo, hi = self.interval_bounds(e, scope)
        return self.dag.const(lo, hi, unique=True)

    def interval_bounds(self, e: ast.IntervalLit, scope: Scope) -> tuple[float, float]:
        """The floats enclosing [lo, hi] (bounds may be infinite); empty is an error."""
        lo, exact_lo = self._bound(e.lo, scope, lower=True)
        hi, exact_hi = self._bound(e.hi, scope, lower=False)
        empty = lo > hi if exact_lo is None or exact_hi is None else exact_lo > exact_hi
        if empty or lo == INF or hi == -INF:
            raise CalError(f"empty interval: lower bound {show(exact_lo, lo)} is above upper "
                           f"bound {show(exact_hi, hi)}" if empty else
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
            raise CalError(f"cannot index {kind_of(value)}", e.loc)
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
            check_arity(e, FUNCTIONS[e.func], "function")
            args = [self.scalar(self.value(a, scope), a.loc, f"an argument of {e.func}")
                    for a in e.args]
            return self.function(e.func, args, e.loc)
        special = SPECIAL_CALLS.get(e.func)
        if special is not None:
            check_arity(e, SPECIAL[e.func], "function")
            return special(self, e, scope)
        macro = self.lookup(e.func, e.loc, scope)
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

    def _rows(self, e: ast.Call, scope: Scope) -> Value:
        """rows(t): the number of rows of table t."""
        table = self.entity(e.args[0], scope)
        if not isinstance(table, TableRef):
            raise CalError("rows(t) takes a table", e.args[0].loc)
        self.row_counts_read += 1
        return Fraction(table.rows)

    def _dot_call(self, e: ast.Call, scope: Scope) -> Value:
        return self._dot(self.value(e.args[0], scope), self.value(e.args[1], scope), e.loc)

    def _dot(self, u: Value, v: Value, loc: Loc) -> Scalar:
        if not (isinstance(u, tuple) and isinstance(v, tuple)):
            raise CalError(f"dot(u, v) takes two vectors, not {kind_of(u)} and {kind_of(v)}", loc)
        total: Scalar = Fraction(0)
        for x, y in pairs(u, v, "multiply", loc):
            total = self.arith("+", total, self.arith("*", x, y, loc), loc)
        return total

    def _rotation(self, e: ast.Call, scope: Scope) -> tuple[int, ...]:
        """euler_xyz(rx, ry, rz): the matrix Rx Ry Rz; compose(A, B): the product A B (3x3
        matrices as 9-vectors, row by row)."""
        values = [self.value(a, scope) for a in e.args]
        if e.func == "euler_xyz":
            angles = [self.node(self.scalar(v, a.loc, "an angle of euler_xyz"), a.loc)
                      for v, a in zip(values, e.args, strict=True)]
            return self.note_rotation(chains.euler_xyz(self.dag, *angles), tuple(angles))
        mats = []
        for v, a in zip(values, e.args, strict=True):
            if not (isinstance(v, tuple) and len(v) == 9):
                raise CalError(f"compose(A, B) takes two 3x3 matrices as 9-vectors (row by "
                               f"row), not {kind_of(v)}", a.loc)
            mats.append(tuple(self.node(x, a.loc) for x in v))
        product = chains.compose(self.dag, mats[0], mats[1])
        if all(self.is_rotation(v) for v in values):
            self.note_rotation(product)
        return product

    def _expand(self, macro: Macro, e: ast.Call, scope: Scope) -> Value:
        if len(e.args) != len(macro.params):
            raise CalError(f"macro '{macro.name}' takes {count(len(macro.params), 'argument')}"
                           f", got {len(e.args)}", e.loc)
        if any(m is macro for m in self.expanding):
            chain = " -> ".join([m.name for m in self.expanding] + [macro.name])
            raise CalError(f"macro '{macro.name}' calls itself ({chain}): macros are expanded "
                           "inline, so recursion is not allowed", e.loc)
        args = [self.entity(a, scope) for a in e.args]
        # A macro is a pure function of its arguments' values: the same call (the same
        # numbers and DAG nodes) gives the same value, so it is expanded once; macros that
        # call another twice at every level stay linear instead of doubling.
        key = (id(macro), *args) if all(type(a) in (int, Fraction, tuple) for a in args) \
            else None
        if key is not None and key in self.expanded:
            return self.expanded[key][1]
        inner = Scope(macro.scope)
        for p, a in zip(macro.params, args, strict=True):
            inner.names[p.id] = (a, p.loc)
        self.expanding.append(macro)
        try:
            value = self.value(macro.body, inner)
        finally:
            self.expanding.pop()
        if key is not None:
            self.expanded[key] = (macro, value)  # (the macro kept alive: its id stays its own)
        return value

    # -- conversions ----------------------------------------------------------------------
    def node(self, v: Scalar, loc: Loc) -> int:
        """The DAG node of a scalar (an exact number becomes its enclosing constant)."""
        if type(v) is int:
            return v
        assert isinstance(v, Fraction)
        found = self._consts.get(v)
        if found is None:
            found = self._consts[v] = self.dag.const(*enclose(v, loc))
        return found

    def scalar(self, v: Value, loc: Loc, what: str) -> Scalar:
        if isinstance(v, tuple):
            raise CalError(f"{what} must be a number, not {kind_of(v)}", loc)
        return v

    def is_constant(self, v: Scalar) -> bool:
        return isinstance(v, Fraction) or self.dag.nodes[v].op == "const"

    def constant_interval(self, v: Value, loc: Loc, what: str) -> tuple[float, float]:
        if isinstance(v, tuple):
            raise CalError(f"{what} must be a number, not {kind_of(v)}", loc)
        if isinstance(v, Fraction):
            return enclose(v, loc)
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
            raise CalError(f"cannot compute {OP_NAMES.get(op, op)} of these constants ({err})",
                           loc) from None
        node = self.dag.nodes[n]
        if node.op == "const" and not node.data[0] <= node.data[1]:
            raise CalError(f"{OP_NAMES.get(op, op)} of these constants has no value (an "
                           "argument is outside the function's domain)", loc)
        return n


# The built-in functions of vectors (scope.py's SPECIAL: name -> arity), by name: a new one
# is a method of Expressions taking the call and its scope, and an entry here and there.
SPECIAL_CALLS: dict[str, Callable[[Expressions, ast.Call, Scope], Value]] = {
    "rows": Expressions._rows,
    "dot": Expressions._dot_call,
    "euler_xyz": Expressions._rotation,
    "compose": Expressions._rotation,
}
