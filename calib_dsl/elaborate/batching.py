"""Rows as a batch dimension: a top-level `for k in a..b` whose body reads k only as the row
of table cells (`m.x[k]`) is elaborated for its first two rows, a template that
compile/replicate.py copies for every row (checking the two copies agree, else the loop is
unrolled as any other).

Why this is the same program as unrolling: the body's DAG depends on k only through the cell
nodes, and a cell with an error bound is an uncertain constant that is never folded, never
simplified and never shared (ir/dag.py), so every row's nodes are the first row's with other
cells. Exact cells (a point: no error bound, a representable decimal) fold and simplify
differently per value, so a loop reading any is unrolled.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import fields, is_dataclass
from fractions import Fraction
from typing import Any

import numpy as np

from calib_dsl.elaborate.checks import MAX_UNROLL
from calib_dsl.elaborate.context import Context
from calib_dsl.elaborate.scope import ColumnRef, Macro, Scope, TableRef
from calib_dsl.elaborate.table_decl import Cells
from calib_dsl.frontend import ast
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.ir.model import Model, RowBatch

BATCH_MIN_ROWS = 3  # fewer rows: nothing to gain, unroll
# Statements a batched body may not hold: declarations would repeat per row.
_NOT_IN_BODY = (ast.Decl, ast.Const, ast.TableDecl, ast.Robot, ast.Include, ast.Units)
_MAX_DEPTH = 20  # macros given k within macros given k


def cell_fields(s: ast.For, scope: Scope) -> list[tuple[ast.Field, Scope]] | None:
    """The `table.column` of each `table.column[k]` the loop's body reads (with the scope to
    read it in), when the loop's variable k appears nowhere else: no arithmetic on k, no name
    that shadows it; passed to a macro, only where the macro's parameter is such a row in
    turn. None otherwise."""
    found: list[tuple[ast.Field, Scope]] = []
    return found if _only_as_row(s.body, s.var.id, scope, found, 0) and found else None


def _only_as_row(node: Any, var: str, scope: Scope, found: list[tuple[ast.Field, Scope]],
                 depth: int) -> bool:
    if isinstance(node, tuple):
        return all(_only_as_row(x, var, scope, found, depth) for x in node)
    if isinstance(node, ast.Index) and isinstance(node.base, ast.Field) \
            and isinstance(node.index, ast.Name) and node.index.id == var:
        found.append((node.base, scope))
        return _only_as_row(node.base, var, scope, found, depth)
    if isinstance(node, ast.Call) and any(_is(a, var) for a in node.args):
        return _macro_rows(node, var, scope, found, depth)
    if isinstance(node, (ast.Name, ast.Ident)):
        return node.id != var
    if isinstance(node, _NOT_IN_BODY):
        return False
    if is_dataclass(node) and not isinstance(node, type):
        return all(_only_as_row(getattr(node, f.name), var, scope, found, depth)
                   for f in fields(node))
    return True


def _is(e: ast.Expr, var: str) -> bool:
    return isinstance(e, ast.Name) and e.id == var


def _macro_rows(call: ast.Call, var: str, scope: Scope,
                found: list[tuple[ast.Field, Scope]], depth: int) -> bool:
    """A macro given k: each parameter that receives k is a row in the macro's body."""
    hit = scope.lookup(call.func)
    macro = hit[0] if hit is not None else None
    if depth > _MAX_DEPTH or not isinstance(macro, Macro) \
            or len(macro.params) != len(call.args):
        return False
    for param, arg in zip(macro.params, call.args, strict=True):
        if _is(arg, var):
            if not _only_as_row(macro.body, param.id, macro.scope, found, depth + 1):
                return False
        elif not _only_as_row(arg, var, scope, found, depth):
            return False
    return True


class Batching(Context):
    """Top-level loops over table rows, compiled once."""

    batch: RowBatch | None
    unroll: bool  # the command line's --unroll: every loop unrolled
    unrolled_model: Callable[[], Model]  # this elaboration again, every loop unrolled

    def batched(self, s: ast.For, scope: Scope) -> bool:
        """Elaborate `s` as a template of two rows and note it as the model's batch; False
        (nothing done) when it does not qualify."""
        if self.unroll or self.batch is not None or self.simulate_rows is not None:
            return False
        found = cell_fields(s, scope)
        if found is None:
            return False
        lo = self.integer(s.range.lo, scope, "a loop bound")
        hi = self.integer(s.range.hi, scope, "a loop bound")
        n = hi - lo + 1
        if n < BATCH_MIN_ROWS or self.loop_product * n > MAX_UNROLL:
            return False  # (the unrolled loop says what is wrong with too many)
        cells = self._cells(found, lo, hi)
        if cells is None:
            return False
        outer, self.loop_product = self.loop_product, n
        try:
            for k in (lo, lo + 1):
                inner = Scope(scope)
                inner.define(s.var, Fraction(k))
                self.block(s.body, inner, top=False)
        finally:
            self.loop_product = outer
        for key, derived in self.derived_columns.items():  # sums of cells (measured.py)
            if isinstance(derived, Cells):
                cells[key] = (derived.lo, derived.hi)
        self.batch = RowBatch(list(range(lo, hi + 1)), (lo, lo + 1), cells, s.loc,
                              self.unrolled_model, _over(s, scope, cells, lo, hi))
        return True

    def _cells(self, found: list[tuple[ast.Field, Scope]], lo: int, hi: int
               ) -> dict[tuple[str, str], tuple[np.ndarray, np.ndarray]] | None:
        """The bounds of the cells the body reads, when every row lo..hi of each is an
        uncertain value; None otherwise (the unrolled loop reports what is wrong)."""
        out = {}
        for f, scope in found:
            try:
                ref = self.entity(f, scope)
            except CalError:
                return None
            if not isinstance(ref, ColumnRef):
                return None
            cells = ref.table.cells[ref.column]
            if not isinstance(cells, Cells) or lo < 1 or hi > len(cells):
                return None
            if np.any(cells.lo[lo - 1:hi] == cells.hi[lo - 1:hi]):
                return None
            out[(cells.table, cells.column)] = (cells.lo, cells.hi)
        return out


def _over(s: ast.For, scope: Scope, cells: dict[tuple[str, str], Any], lo: int,
          hi: int) -> str | None:
    """The table t when the loop is `for k in 1..rows(t)` over all of t's rows and its body
    reads cells of t alone: then the same model with fewer rows of t is this one's loop over
    those rows (elaborate/subset.py); else None."""
    end = s.range.hi
    if lo != 1 or not isinstance(end, ast.Call) or end.func != "rows" or len(end.args) != 1:
        return None
    hit = scope.lookup(end.args[0].id) if isinstance(end.args[0], ast.Name) else None
    table = hit[0] if hit is not None else None
    if not isinstance(table, TableRef) or table.rows != hi:
        return None
    return table.name if {t for t, _ in cells} == {table.name} else None
