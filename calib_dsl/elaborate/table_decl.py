"""Table declarations: the columns a model reads from a measurement file, their error
bounds, and the DAG constants (or, in simulation mode, variables) of every cell.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from typing import overload

import numpy as np

from calib_dsl.elaborate.checks import (
    INF,
)
from calib_dsl.elaborate.context import Context
from calib_dsl.elaborate.rows import RowRange, Selection, parse_numbers, parse_ranges
from calib_dsl.elaborate.scope import (
    Scope,
    TableRef,
)
from calib_dsl.elaborate.tables import Dialect, cell_bounds, read_csv
from calib_dsl.elaborate.units import UNITS, convert, dimension, factor
from calib_dsl.elaborate.values import Values, read_values
from calib_dsl.frontend import ast
from calib_dsl.frontend.diagnostics import CalError, Loc
from calib_dsl.ir.dag import Dag
from calib_dsl.ir.model import Column, Table

OPTIONS = ("separator", "decimal", "rows", "exclude")


class Cells(Sequence[int]):
    """A column's cell nodes, each made when first read (row k at index k - 1): a loop
    compiled once reads two rows of thousands (elaborate/batching.py)."""

    def __init__(self, dag: Dag, table: str, column: str, lo: np.ndarray,
                 hi: np.ndarray) -> None:
        self.dag, self.table, self.column = dag, table, column
        self.lo, self.hi = lo, hi  # each cell's bounds, in the model's units
        self._made: dict[int, int] = {}

    def __len__(self) -> int:
        return len(self.lo)

    @overload
    def __getitem__(self, i: int) -> int: ...
    @overload
    def __getitem__(self, i: slice) -> list[int]: ...

    def __getitem__(self, i: int | slice) -> int | list[int]:
        if isinstance(i, slice):
            return [self[k] for k in range(*i.indices(len(self)))]
        if i < 0:
            i += len(self)
        node = self._made.get(i)
        if node is None:
            if not 0 <= i < len(self):
                raise IndexError(i)
            node = self._made[i] = self.dag.cell(float(self.lo[i]), float(self.hi[i]),
                                                  self.table, self.column, i + 1)
        return node


class Tables(Context):
    """`table` declarations."""

    # -- tables ---------------------------------------------------------------------------
    def _table(self, s: ast.TableDecl, scope: Scope, top: bool) -> None:
        self._top_only("a table declaration", s.loc, top)
        scope.check_new(s.name)
        columns, locs = self._columns(s, scope)
        dialect, selection, selection_loc = self._options(s, scope)
        override = self.data.get(s.name.id) or (self.data.get("") if not self.tables else None)
        path = str(override) if override is not None else \
            os.path.normpath(os.path.join(os.path.dirname(s.loc.file), s.path))
        table = Table(s.name.id, path, columns, 0, s.loc, dialect.separator, dialect.decimal,
                      selects=any(o.name.id in ("rows", "exclude") for o in s.options))
        cells: dict[str, Sequence[int]]
        if self.simulate_rows is not None:
            table.rows = self.simulate_rows
            cells = {c.name: [self.dag.var(f"{s.name.id}.{c.name}[{k}]", -INF, INF,
                                           locs[c.name], kind="data")
                              for k in range(1, table.rows + 1)] for c in columns}
        else:
            if isinstance(override, Values):  # the Python API's arrays, where a file would be
                data = read_values(override, [c.name for c in columns], s.name.id, selection,
                                   s.loc)
            else:
                data = read_csv(path, [c.name for c in columns],
                                None if override is not None else s.path_loc, dialect=dialect,
                                headers={c.name: c.header for c in columns if c.header},
                                selection=selection, selection_loc=selection_loc)
            table.rows, table.lines, table.numbers = data.rows, data.lines, data.numbers
            cells = {}
            for c in columns:
                table.readings[c.name] = convert(*data.enclosures[c.name], c.factor)
                lo, hi = cell_bounds(*table.readings[c.name], c.tol)
                cells[c.name] = Cells(self.dag, s.name.id, c.name, lo, hi)
                table.bounds[c.name] = (lo, hi)
        self.tables.append(table)
        scope.define(s.name, TableRef(s.name.id, table.rows, cells))

    def _options(self, s: ast.TableDecl, scope: Scope
                 ) -> tuple[Dialect, Selection, Loc | None]:
        """The file's dialect and the rows to use: the table's options, then the command
        line's (`--rows`, which replaces the table's selection)."""
        given: dict[str, ast.TableOption] = {}
        for o in s.options:
            if o.name.id not in OPTIONS:
                raise CalError(f"unknown table option '{o.name.id}' (the options are "
                               f"{', '.join(OPTIONS)})", o.name.loc)
            if o.name.id in given:
                raise CalError(f"table option '{o.name.id}' given twice", o.name.loc)
            given[o.name.id] = o
        separator = self._text_option(given.get("separator"), ",")
        decimal = self._text_option(given.get("decimal"), ".")
        if separator not in (",", ";", "\t", "tab", " ", "|"):
            raise CalError(f"separator '{separator}': use one of ',' ';' '|' ' ' or \"tab\"",
                           given["separator"].loc)
        separator = "\t" if separator == "tab" else separator
        if decimal not in (".", ","):
            raise CalError(f"decimal mark '{decimal}': use '.' or ','", given["decimal"].loc)
        if decimal == separator:
            raise CalError("the decimal mark and the separator must differ",
                           given["decimal"].loc)
        ranges = self._row_ranges(given["rows"], scope) if "rows" in given else ()
        excluded = self._row_numbers(given["exclude"], scope) if "exclude" in given else ()
        loc = (given.get("rows") or given.get("exclude") or s).loc
        cli = self.selections.get(s.name.id) or (self.selections.get("") if not self.tables
                                                 else None)
        if cli is not None:  # --rows replaces the table's ranges, --exclude adds rows
            ranges = cli.ranges or ranges
            excluded = tuple(sorted(set(excluded) | set(cli.excluded)))
        return Dialect(separator, decimal), Selection(ranges, excluded), \
            None if cli is not None else loc

    def _text_option(self, o: ast.TableOption | None, default: str) -> str:
        if o is None:
            return default
        if not isinstance(o.value, str):
            raise CalError(f"table option '{o.name.id}' is a \"string\"", o.loc)
        return o.value

    def _row_ranges(self, o: ast.TableOption, scope: Scope) -> tuple[RowRange, ...]:
        """`rows = 1..1495:15` (numbers may be constants), or a string of ranges."""
        try:
            if isinstance(o.value, str):
                return parse_ranges(o.value)
            if isinstance(o.value, ast.RowRange):
                r = o.value
                first = self.integer(r.first, scope, "a row number")
                last = None if r.last is None else self.integer(r.last, scope, "a row number")
                step = 1 if r.step is None else self.integer(r.step, scope, "a step")
                return parse_ranges(f"{first}..{'' if last is None else last}:{step}")
            return parse_ranges(str(self.integer(o.value, scope, "a row number")))
        except ValueError as err:
            raise CalError(str(err), o.loc) from None

    def _row_numbers(self, o: ast.TableOption, scope: Scope) -> tuple[int, ...]:
        """`exclude = 533`, `exclude = (533, 856)` or a string of numbers."""
        if isinstance(o.value, str):
            try:
                return parse_numbers(o.value)
            except ValueError as err:
                raise CalError(str(err), o.loc) from None
        if isinstance(o.value, ast.RowRange):
            raise CalError("exclude takes row numbers, e.g. exclude = (533, 856)", o.loc)
        items = o.value.items if isinstance(o.value, ast.TupleLit) else (o.value,)
        return tuple(self.integer(e, scope, "a row number") for e in items)

    def _columns(self, s: ast.TableDecl, scope: Scope) -> tuple[list[Column], dict[str, Loc]]:
        columns: list[Column] = []
        locs: dict[str, Loc] = {}
        for g in s.groups:
            tol = self._tolerance(g.tol, scope)
            if isinstance(g.tol, ast.Name) and self.is_global_const(g.tol.id,
                                                                    scope.lookup(g.tol.id)):
                n, cols = self.tolerance_of.get(g.tol.id, (0, []))
                self.tolerance_of[g.tol.id] = (n + 1, cols + [(s.name.id, i.id)
                                                              for i in g.names])
            sim = None
            if g.simulate is not None:
                lo, hi, _ = self.domain(g.simulate, scope)
                if not (math.isfinite(lo) and math.isfinite(hi)):
                    raise CalError("a simulation range must be finite (values are drawn "
                                   "uniformly in it)", g.simulate.loc)
                sim = (lo, hi)
            headers = g.headers or (None,) * len(g.names)
            units = g.units or (None,) * len(g.names)
            for ident, header, unit in zip(g.names, headers, units, strict=True):
                if ident.id in locs:
                    raise CalError(f"column '{ident.id}' is already declared (at "
                                   f"{locs[ident.id]})", ident.loc)
                locs[ident.id] = ident.loc
                columns.append(Column(ident.id, tol, sim, header,
                                      *self._unit(unit)))
        if not columns:
            raise CalError(f"table '{s.name.id}' declares no column", s.loc)
        return columns, locs

    def _unit(self, unit: ast.Ident | None) -> tuple[str | None, tuple[float, float]]:
        """A column's unit in the file, and the factor that converts it to the model's."""
        if unit is None:
            return None, (1.0, 1.0)
        if unit.id not in UNITS:
            raise CalError(f"unknown unit '{unit.id}' (the units are {', '.join(UNITS)})",
                           unit.loc)
        return unit.id, factor(unit.id, self.units[dimension(unit.id)])

    def _tolerance(self, e: ast.Expr, scope: Scope) -> float:
        lo, hi = self.constant_interval(self.value(e, scope), e.loc, "a tolerance")
        if lo < 0:
            raise CalError(f"a tolerance must be >= 0, not {lo!r}", e.loc)
        if not math.isfinite(hi):
            raise CalError("a tolerance must be finite", e.loc)
        return hi
