"""The same elaborated model with fewer rows of its table, or another error bound, without
elaborating it again.

A model whose rows enter only through one loop compiled once (elaborate/batching.py) over
all the rows of its one table, `for k in 1..rows(t)`, is its two template rows' DAG and the
table's cells: elaborated with rows left out, it is the same DAG, the template's cells
those of the first two rows kept, and the loop over the rows kept, renumbered 1..n. The
template's cell nodes are uncertain constants that nothing folds (ir/dag.py), so changing
their values leaves every other node as it was. Any other use of the rows (`rows(t)` read
elsewhere, a cell read outside the loop, another table, fewer rows than a batch needs) and
`rows_of` answers None: the caller elaborates anew.

The same model can read another file's rows as its table's (`with_table`: held-out
configurations to predict at): the template's cells and the loop's rows are the file's, the
cells' bounds made from its readings as the elaborator makes them, where the model is
derivable, its table's declaration selects no rows itself and has no derived column.

A const read only as the whole error bound of columns (`x, y : +- e`, `Model.tolerances`)
enters the model through those columns' cells alone: set to another value, it is the same
DAG with those cells (never folded, never shared) widened or narrowed from the readings
(`with_tolerance`). A bound of 0 makes exact cells, which fold: elaborated anew.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from fractions import Fraction

import numpy as np

from calib_dsl.arith.exact import enclose_fraction
from calib_dsl.elaborate.batching import BATCH_MIN_ROWS
from calib_dsl.elaborate.tables import CsvData, cell_bounds
from calib_dsl.elaborate.units import convert
from calib_dsl.ir.dag import Dag
from calib_dsl.ir.model import Model, RowBatch, Table


def derivable(model: Model) -> bool:
    """Whether `rows_of` can give this model with fewer rows (see the module's doc)."""
    batch = model.batch
    if model.simulation or batch is None or batch.table is None or model.row_counts_read != 1 \
            or len(model.tables) != 1 or model.tables[0].name != batch.table:
        return False
    tags = list(model.dag.cells.values())
    rows = {row for ts in tags for t, _, row in ts if t == batch.table}
    return rows <= set(batch.template) and all(len(ts) == 1 for ts in tags)


def rows_of(model: Model, keep: list[int], unrolled: Callable[[], Model]) -> Model | None:
    """The model with only its rows `keep` (model row numbers k, 1-based, increasing), or
    None when it must be elaborated anew; `unrolled`: that model elaborated with every loop
    unrolled (what compiling falls back to if its template rows are no copies)."""
    batch = model.batch
    if not derivable(model) or batch is None or len(keep) < BATCH_MIN_ROWS \
            or any(b <= a for a, b in zip(keep, keep[1:], strict=False)) \
            or keep[0] < 1 or keep[-1] > len(batch.rows):
        return None
    at = np.array(keep, dtype=np.int64) - 1
    cells = {key: (lo[at], hi[at]) for key, (lo, hi) in batch.cells.items()}
    new_batch = RowBatch(list(range(1, len(keep) + 1)), batch.template, cells, batch.loc,
                         unrolled, batch.table)
    return replace(model, dag=_template_cells(model.dag, cells),
                   tables=[_rows_of_table(model.tables[0], at)], batch=new_batch)


def with_table(model: Model, data: CsvData, unrolled: Callable[[], Model]) -> Model | None:
    """The model with the rows `data` (every column of its table, read in the file's units)
    as its table's, or None when it must be elaborated anew (see the module's doc)."""
    batch = model.batch
    if not derivable(model) or batch is None or data.rows < BATCH_MIN_ROWS:
        return None
    t = model.tables[0]
    if t.selects or any(c.derived or c.name not in data.enclosures for c in t.columns):
        return None
    readings = {c.name: convert(*data.enclosures[c.name], c.factor) for c in t.columns}
    bounds = {c.name: cell_bounds(*readings[c.name], c.tol) for c in t.columns}
    cells = {key: bounds[key[1]] for key in batch.cells}
    new_batch = RowBatch(list(range(1, data.rows + 1)), batch.template, cells, batch.loc,
                         unrolled, batch.table)
    table = replace(t, path=data.path, rows=data.rows, lines=list(data.lines),
                    numbers=list(data.numbers), bounds=bounds, readings=readings,
                    columns=list(t.columns))
    return replace(model, dag=_template_cells(model.dag, cells), tables=[table],
                   batch=new_batch)


def _rows_of_table(t: Table, at: np.ndarray) -> Table:
    return replace(t, rows=len(at), lines=[t.lines[i] for i in at.tolist()],
                   numbers=[t.numbers[i] for i in at.tolist()],
                   bounds={c: (lo[at], hi[at]) for c, (lo, hi) in t.bounds.items()},
                   readings={c: (lo[at], hi[at]) for c, (lo, hi) in t.readings.items()},
                   columns=list(t.columns))


def with_tolerance(model: Model, name: str, value: Fraction) -> Model | None:
    """The model with the const `name` (an error bound of columns alone) set to `value`, or
    None when it must be elaborated anew (see the module's doc)."""
    columns = set(model.tolerances.get(name, ()))
    try:
        lo, tol = enclose_fraction(value)
    except OverflowError:
        return None
    tables = {t.name: t for t in model.tables}
    if not columns or model.simulation or not (0 < lo and np.isfinite(tol)) \
            or any(c.derived for t in model.tables for c in t.columns) \
            or any(c not in tables[t].readings for t, c in columns) \
            or any(c.name == col and c.tol <= 0 for t, col in columns
                   for c in tables[t].columns):
        return None
    bounds = {(t, c): cell_bounds(*tables[t].readings[c], tol) for t, c in columns}
    new_tables = [_with_bounds(t, bounds, tol) for t in model.tables]
    batch = model.batch
    if batch is not None:
        batch = replace(batch, cells={k: bounds.get(k, v) for k, v in batch.cells.items()})
    values = {}
    for node, tags in model.dag.cells.items():
        hit = [(t, c, row) for t, c, row in tags if (t, c) in bounds]
        if hit:
            if len(tags) != 1:
                return None
            (t, c, row), = hit
            values[node] = (float(bounds[(t, c)][0][row - 1]),
                            float(bounds[(t, c)][1][row - 1]))
    return replace(model, dag=model.dag.with_cells(values), tables=new_tables, batch=batch,
                   consts={**model.consts, name: value})


def _with_bounds(t: Table, bounds: dict[tuple[str, str], tuple[np.ndarray, np.ndarray]],
                 tol: float) -> Table:
    mine = {c for name, c in bounds if name == t.name}
    return replace(t, columns=[replace(c, tol=tol) if c.name in mine else c for c in t.columns],
                   bounds={**t.bounds, **{c: bounds[(t.name, c)] for c in mine}})


def _template_cells(dag: Dag, cells: dict[tuple[str, str], tuple[np.ndarray, np.ndarray]]
                    ) -> Dag:
    """A copy of `dag` whose template rows' cells hold the values of the rows now first
    (template row j: the j-th row kept); the same nodes otherwise."""
    values = {}
    for node, tags in dag.cells.items():
        (table, column, row), = tags  # (`derivable`: one each)
        if (table, column) in cells:
            lo, hi = cells[(table, column)]
            values[node] = (float(lo[row - 1]), float(hi[row - 1]))
    return dag.with_cells(values)
