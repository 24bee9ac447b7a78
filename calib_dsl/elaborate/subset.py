"""The same elaborated model with fewer rows of its table, without elaborating it again.

A model whose rows enter only through one loop compiled once (elaborate/batching.py) over
all the rows of its one table, `for k in 1..rows(t)`, is its two template rows' DAG and the
table's cells: elaborated with rows left out, it is the same DAG, the template's cells
those of the first two rows kept, and the loop over the rows kept, renumbered 1..n. The
template's cell nodes are uncertain constants that nothing folds (ir/dag.py), so changing
their values leaves every other node as it was. Any other use of the rows (`rows(t)` read
elsewhere, a cell read outside the loop, another table, fewer rows than a batch needs) and
`rows_of` answers None: the caller elaborates anew.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from calib_dsl.elaborate.batching import BATCH_MIN_ROWS
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


def _rows_of_table(t: Table, at: np.ndarray) -> Table:
    return replace(t, rows=len(at), lines=[t.lines[i] for i in at.tolist()],
                   numbers=[t.numbers[i] for i in at.tolist()],
                   bounds={c: (lo[at], hi[at]) for c, (lo, hi) in t.bounds.items()},
                   columns=list(t.columns))


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
