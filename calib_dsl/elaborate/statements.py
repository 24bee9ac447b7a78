"""Statements: files and includes, definitions, loops, declarations of unknowns and
constraints; what each adds to the scope and the DAG.
"""

from __future__ import annotations

import itertools
import math
import os
from fractions import Fraction
from pathlib import Path

from calib_dsl.elaborate.checks import (
    INF,
    MAX_UNROLL,
    check_params,
    nearest,
    pairs,
)
from calib_dsl.elaborate.context import Context
from calib_dsl.elaborate.scope import (
    Family,
    Macro,
    Scope,
    Value,
)
from calib_dsl.elaborate.units import UNITS, dimension
from calib_dsl.frontend import ast
from calib_dsl.frontend.diagnostics import CalError, Loc
from calib_dsl.frontend.parser import parse_file


class Statements(Context):
    """The statements of a model, elaborated in order."""

    # -- files and statements -------------------------------------------------------------
    def file(self, shown: str) -> None:
        resolved = Path(shown).resolve()
        self.sources.append(shown)
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
        if top:
            self.consts_seen.add(s.name.id)
        if top and s.name.id in self.overrides:  # -D name=value: the command line's value
            value: Value = self._override(s)
        else:
            value = self.value(s.value, scope)
            items = value if isinstance(value, tuple) else (value,)
            if not all(self.is_constant(x) for x in items):
                raise CalError(f"const '{s.name.id}' depends on unknowns: a const must be a "
                               "constant expression (use let for an alias)", s.value.loc)
        if top and isinstance(value, Fraction):
            self.const_values[s.name.id] = value
        scope.define(s.name, value)

    def _override(self, s: ast.Const) -> Fraction:
        text = self.overrides[s.name.id]
        self.overridden.add(s.name.id)
        try:
            return Fraction(text.strip())
        except (ValueError, ZeroDivisionError):
            raise CalError(f"-D {s.name.id}={text}: the value must be a number (as 1.2, "
                           "-3e-4 or 1/3)", s.loc) from None

    def _units(self, s: ast.Units, scope: Scope, top: bool) -> None:
        """`units mm, rad;`: the model's length and angle units, once, before any table."""
        self._top_only("a units statement", s.loc, top)
        if self.units_loc is not None:
            raise CalError(f"the units are already stated (at {self.units_loc})", s.loc)
        if self.tables:
            raise CalError("state the units before the first table (its columns are "
                           "converted to them)", s.loc)
        seen: dict[str, str] = {}
        for u in s.names:
            if u.id not in UNITS:
                raise CalError(f"unknown unit '{u.id}' (the units are {', '.join(UNITS)})",
                               u.loc)
            dim = dimension(u.id)
            if dim in seen:
                raise CalError(f"two {dim} units ('{seen[dim]}' and '{u.id}')", u.loc)
            seen[dim] = u.id
        self.units.update(seen)
        self.units_loc = s.loc

    def _let(self, s: ast.Let, scope: Scope, top: bool) -> None:
        scope.define(s.name, self.entity(s.value, scope))

    def _def(self, s: ast.Def, scope: Scope, top: bool) -> None:
        check_params(s.params, "parameter")
        scope.define(s.name, Macro(s.name.id, s.params, s.body, scope))

    def _for(self, s: ast.For, scope: Scope, top: bool) -> None:
        if top and self.batched(s, scope):
            return
        self.unrolled(s.var, s.range, scope, s.loc, "loop",
                      lambda inner: self.block(s.body, inner, top=False))

    def _include(self, s: ast.Include, scope: Scope, top: bool) -> None:
        self._top_only("include", s.loc, top)
        shown = os.path.normpath(os.path.join(os.path.dirname(s.loc.file), s.path))
        if Path(shown).is_dir():
            raise CalError(f"include file '{s.path}' is a directory ('{shown}'): include "
                           "names a .cal file", s.loc)
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
        # an orientation reading: three measured angles, and the matrices they imply equal
        angles = self.orientation_pairs(lhs, rhs) if s.rel == "==" else None
        for left, right in angles or []:
            self.dag.constrain(left, s.rel, right, s.loc)
        for a, b in pairs(lhs, rhs, "compare", s.rel_loc):
            left, right = self.node(a, s.lhs.loc), self.node(b, s.rhs.loc)
            if s.rel == "==":  # a measured side that sums cells, one with an error: one reading
                left, right = self.measured_pair(left, right) or (left, right)
            self.dag.constrain(left, s.rel, right, s.loc, implied=angles is not None)

    # -- declarations of unknowns ---------------------------------------------------------
    def _decl(self, s: ast.Decl, scope: Scope, top: bool) -> None:
        self._top_only(f"a {s.kind} declaration", s.loc, top)
        prior = self._lsq_prior(s.domain, scope)
        lo, hi, center = (-INF, INF, None) if prior else self.domain(s.domain, scope)
        true = center if s.true is None else self.true_value(s.true, scope)
        for dn in s.names:
            scope.check_new(dn.name)
            if dn.dims:
                scope.define(dn.name, self._family(s, dn, scope, (lo, hi), true))
            else:
                t = self._check_true(true, s, dn.name.id, lo, hi)
                node = self.dag.var(dn.name.id, lo, hi, dn.name.loc, kind=s.kind, true=t)
                self.dag.variables[dn.name.id].prior = prior
                self.dag.variables[dn.name.id].true_stated = s.true is not None
                scope.define(dn.name, node)

    def _lsq_prior(self, e: ast.Expr | None, scope: Scope) -> tuple[float, float] | None:
        """`lsq +- w` or `lsq(start) +- w`: (start, w), else None. The domain is centred on
        the least-squares estimate of the data at hand once the program is compiled (for a
        base that stands somewhere else in each measurement campaign)."""
        if not (isinstance(e, ast.BinOp) and e.op == "+-"):
            return None
        left = e.left
        if isinstance(left, ast.Name) and left.id == "lsq" and scope.lookup("lsq") is None:
            start = 0.0
        elif isinstance(left, ast.Call) and left.func == "lsq" and scope.lookup("lsq") is None:
            if len(left.args) != 1:
                raise CalError("lsq(start) takes one value: where the least-squares search "
                               "starts", left.loc)
            start = self._point(left.args[0], scope, "the start of lsq")
        else:
            return None
        w = self._point(e.right, scope, "the half-width of an lsq domain")
        if not (math.isfinite(w) and w > 0):
            raise CalError("the half-width of an lsq domain must be finite and > 0", e.right.loc)
        return start, w

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
            self.dag.variables[name].true_stated = s.true is not None
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
            lo, hi = self.interval_bounds(e, scope)
            return lo, hi, None
        v = self.value(e, scope)
        lo, hi = self.constant_interval(v, e.loc, "a domain")
        center = None
        if isinstance(e, ast.BinOp) and e.op == "+-":
            center = self._point(e.left, scope, "the center of '+-'")
        elif isinstance(v, Fraction):
            center = nearest(v, e.loc)
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
            return nearest(v, e.loc)
        lo, hi = self.constant_interval(v, e.loc, what)
        if not (math.isfinite(lo) and math.isfinite(hi)):
            raise CalError(f"{what} must be finite", e.loc)
        mid = lo if lo == hi else 0.5 * lo + 0.5 * hi
        if hi - lo > 1e-9 * max(1.0, abs(mid)):  # wider than rounding: a real interval
            raise CalError(f"{what} must be a number, not an interval [{lo!r}, {hi!r}]", e.loc)
        return mid
