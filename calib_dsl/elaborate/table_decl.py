"""Table declarations: the columns a model reads from a measurement file, their error
bounds, and the DAG constants (or, in simulation mode, variables) of every cell.
"""

from __future__ import annotations

import math
import os

from calib_dsl.elaborate.checks import (
    INF,
)
from calib_dsl.elaborate.context import Context
from calib_dsl.elaborate.scope import (
    Scope,
    TableRef,
)
from calib_dsl.elaborate.tables import cell_bounds, read_csv
from calib_dsl.frontend import ast
from calib_dsl.frontend.diagnostics import CalError, Loc
from calib_dsl.ir.model import Column, Table


class Tables(Context):
    """`table` declarations."""

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
