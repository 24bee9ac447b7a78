"""One data row, however it is spelled: a measured side that is a sum of exact table cells and
one cell with an error bound is one reading.

`robot(q) at p == m.target[k] + m.dif[k]` (dif known to +- e, target exact) and
`robot(q) at p - m.target[k] == m.dif[k]` state the same thing. Compiled as written, the first
compares the robot with a computed sum of two cells (two readings, no measured side) and the
second subtracts a cell from the robot. Both become `robot(q) at p == c` with c the cell
`target + dif` of a derived column: its interval, row by row, is the sum of the cells'
intervals rounded outward (so it holds every value the two cells allow), and every spelling of
the same mathematics compiles to the same program.

The rule: the constraint is an equality; one side, after its cells are taken out of its
sums, differences and negations, still holds something computed, the other side none; the
cells moved to the measured side all come from one row of one table, each with coefficient
+1 or -1, exactly one of them from a column with an error bound, and at least one from an
exact column (`: +- 0`). Anything else is compiled as written.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from calib_dsl.arith.exact import add_rounded
from calib_dsl.elaborate.context import Context
from calib_dsl.elaborate.table_decl import Cells
from calib_dsl.ir.model import Column, Table

# How deep a side's sums are searched for cells: a measured side is written by hand, a few
# terms at its top; deeper sums are the model's own arithmetic, never a reading.
_PEEL_DEPTH = 12

Terms = list[tuple[int, int]]  # (sign +1 or -1, node)


class Measured(Context):
    """Constraints whose measured side is a sum of cells, as one reading."""

    def measured_pair(self, lhs: int, rhs: int) -> tuple[int, int] | None:
        """(computed side, derived cell) when `lhs == rhs` is such a constraint, else None."""
        lcore, lcells = self._peel(lhs, 1, 0)
        rcore, rcells = self._peel(rhs, 1, 0)
        if not (lcells or rcells) or bool(lcore) == bool(rcore):
            return None
        core, cells = (lcore, rcells + [(-s, n) for s, n in lcells]) if lcore \
            else (rcore, lcells + [(-s, n) for s, n in rcells])
        if all(s < 0 for s, _ in core):  # -f == c is f == -c
            core, cells = [(-s, n) for s, n in core], [(-s, n) for s, n in cells]
        found = self._cell_terms(cells)
        if found is None:
            return None
        table, row, signs = found
        cell = self._derived(table, signs)[row - 1]
        return self._rebuilt(core), cell

    def _peel(self, node: int, sign: int, depth: int) -> tuple[Terms, Terms]:
        """The node as (computed terms, cell terms), each with its sign; a sum holding no
        cell stays one computed term (its node unchanged)."""
        dag = self.dag
        if node in dag.cells:
            return [], [(sign, node)]
        if node in self.negated_cells:
            return [], [(-sign, self.negated_cells[node])]
        n = dag.nodes[node]
        if depth >= _PEEL_DEPTH or n.op not in ("add", "sub", "neg"):
            return [(sign, node)], []
        if n.op == "neg":
            core, cells = self._peel(n.args[0], -sign, depth + 1)
        else:
            ca, xa = self._peel(n.args[0], sign, depth + 1)
            cb, xb = self._peel(n.args[1], -sign if n.op == "sub" else sign, depth + 1)
            core, cells = ca + cb, xa + xb
        return ([(sign, node)], []) if not cells else (core, cells)

    def _cell_terms(self, cells: Terms) -> tuple[Table, int, dict[str, int]] | None:
        """The table, row and signed columns of cell terms that qualify, else None."""
        coef: dict[tuple[str, str, int], int] = {}
        single = [next(iter(self.dag.cells[n])) for _, n in cells if len(self.dag.cells[n]) == 1]
        rows = {(t, r) for t, _, r in single}
        for s, node in cells:
            # an exact value several cells share (equal numbers are one node): the one of
            # this row's
            tags = [k for k in self.dag.cells[node] if (k[0], k[2]) in rows]
            if len(tags) != 1:
                return None
            coef[tags[0]] = coef.get(tags[0], 0) + s
        coef = {k: c for k, c in coef.items() if c}
        if len({(t, r) for t, _, r in coef}) != 1 or any(abs(c) != 1 for c in coef.values()):
            return None
        table = next(t for t in self.tables if t.name == next(iter(coef))[0])
        tol = {c.name: c.tol for c in table.columns}
        if any(c not in tol for _, c, _ in coef):  # (a derived column already)
            return None
        errors = sum(tol[c] > 0 for _, c, _ in coef)
        if errors != 1 or len(coef) < 2:
            return None
        row = next(iter(coef))[2]
        return table, row, {c: s for (_, c, _), s in coef.items()}

    def _derived(self, table: Table, signs: dict[str, int]) -> Sequence[int]:
        """The cells of the column `signs` sums (made once per table and sum)."""
        order = [c.name for c in table.columns]
        terms = sorted(signs.items(), key=lambda kv: order.index(kv[0]))
        name = "".join(("-" if s < 0 else "+" if i else "") + c
                       for i, (c, s) in enumerate(terms))
        found = self.derived_columns.get((table.name, name))
        if found is not None:
            return found
        lo = hi = None
        for c, s in terms:
            clo, chi = table.bounds[c]
            a, b = (clo, chi) if s > 0 else (-chi, -clo)
            lo = a if lo is None else add_rounded(lo, a, -1.0)
            hi = b if hi is None else add_rounded(hi, b, 1.0)
        assert lo is not None and hi is not None
        error = next(col for col in table.columns if col.name in signs and col.tol > 0)
        table.columns.append(Column(name, error.tol, derived=tuple(c for c, _ in terms)))
        table.bounds[name] = (np.asarray(lo), np.asarray(hi))
        cells = Cells(self.dag, table.name, name, np.asarray(lo), np.asarray(hi))
        self.derived_columns[(table.name, name)] = cells
        return cells

    def _rebuilt(self, core: Terms) -> int:
        """The computed terms as one node: the positive ones added in order, then the
        negative ones subtracted (a single term is its own node)."""
        ordered = [t for t in core if t[0] > 0] + [t for t in core if t[0] < 0]
        sign, acc = ordered[0]
        if sign < 0:
            acc = self.dag.op("neg", acc)
        for s, node in ordered[1:]:
            acc = self.dag.op("add" if s > 0 else "sub", acc, node)
        return acc
