"""The predicted configurations' own joint readings moved within their tolerance, for the
predictions' inner ends.

A prediction's outer box holds the predicted measurement for every consistent parameter
vector and every value of the configuration's readings within their errors (the mean-value
form charges |D| e, the second-order form's remainder holds the readings' errors). So a
prediction at a certified point with the readings anywhere inside their (exact) intervals is
a value the prediction truly takes, as much as the one at the readings' middles. An inner end
is pushed outward by evaluating its certified point with each reading at the end of its
interval the prediction's derivative in that reading points to (upward for the high end,
downward for the low one): the sign of the middle of its enclosure over the box (a sign of
0, or a row whose readings mix configurations, keeps the middle). The sign only aims; the
value is the exact evaluation's (accuracy/certified.py), so a wrong sign costs width, never
soundness. The readings are kept within exact_inside of their slots' intervals, which the
point check itself requires.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_dsl.analysis.certify_point import exact_inside, reading_slots
from calib_dsl.ir.model import Table
from calib_dsl.ir.program import Program


@dataclass(frozen=True)
class Moves:
    """Readings of the held program's reading slots (`reading_slots` order): one vector per
    (predicted column, side) in `configs`; `of` (targets, 2): which vector each target's
    highest pick (column 0) and lowest pick (column 1) is evaluated at (the layout of
    accuracy/certified.py `picks`)."""

    configs: np.ndarray
    of: np.ndarray


def reading_moves(prog: Program, targets: np.ndarray, slope: np.ndarray,
                  owner: np.ndarray) -> Moves | None:
    """The readings that push each target slot's inner ends outward: `slope` (targets,
    table columns) the middles of the targets' derivatives in their configuration's
    readings, `owner` (targets,) that configuration (cell_row id; negative: none or
    several). None where the program has no readings to move."""
    s = prog.slots
    at = reading_slots(prog)
    if not len(at) or s.cell_row is None or s.cell_col is None or s.measured_sides is None:
        return None
    column = np.array([s.measured_sides[int(t)][1] for t in targets], dtype=np.int64)
    columns = np.unique(column)
    lo, hi = s.lo[at], s.hi[at]
    mid = 0.5 * lo + 0.5 * hi  # (the point check's default: the readings' middles)
    rlo, rhi = exact_inside(lo, hi)
    movable = (rlo <= mid) & (mid <= rhi)
    rows, cols = s.cell_row[at], s.cell_col[at]
    configs = np.repeat(mid[None], 2 * len(columns), axis=0)
    for c_at, c in enumerate(columns):
        mine = np.flatnonzero((column == c) & (owner >= 0))
        sign = _signs(rows, cols, owner[mine], slope[mine])
        for side, row in ((1.0, 2 * c_at), (-1.0, 2 * c_at + 1)):
            d = side * sign
            configs[row] = np.where(movable & (d > 0), rhi,
                                    np.where(movable & (d < 0), rlo, mid))
    c_of = np.searchsorted(columns, column)
    return Moves(configs, np.stack([2 * c_of, 2 * c_of + 1], axis=1))


def _signs(rows: np.ndarray, cols: np.ndarray, owner: np.ndarray, slope: np.ndarray
           ) -> np.ndarray:
    """Per reading slot (its configuration `rows` and table column `cols`), the sign of
    the slope in it of the target (one a row of `slope`) whose configuration is its
    (`owner`); 0 where no target has it."""
    out = np.zeros(len(rows))
    if not len(owner):
        return out
    order = np.argsort(owner, kind="stable")
    at = np.minimum(np.searchsorted(owner[order], rows), len(order) - 1)
    hit = owner[order[at]] == rows
    inside = hit & (cols >= 0) & (cols < slope.shape[1])
    t = order[at[inside]]
    out[inside] = np.sign(slope[t, cols[inside]])
    return out


def held_values(prog: Program, table: Table, moves: Moves | None, read: np.ndarray
                ) -> tuple[tuple[str, ...], np.ndarray]:
    """The table's reading columns (in its order) and, per cell end of `read` ((rows,
    columns, 2): a row of `moves.configs`, -1 the readings' middles), the configuration's
    readings it was evaluated at ((rows, columns, 2, reading columns))."""
    s = prog.slots
    at = reading_slots(prog)
    if s.cell_row is None or s.cell_col is None or s.row_keys is None or s.col_keys is None:
        return (), np.zeros((*read.shape, 0))
    mine = np.array([s.row_keys[int(r)][0] == table.name for r in s.cell_row[at]], dtype=bool)
    names = [c.name for c in table.columns]
    present = {s.col_keys[int(c)][1] for c in s.cell_col[at][mine]}
    columns = tuple(n for n in names if n in present)
    mid = 0.5 * s.lo[at] + 0.5 * s.hi[at]
    configs = np.vstack([mid[None] if moves is None else moves.configs, mid[None]])
    rows = np.array([s.row_keys[int(r)][1] - 1 for r in s.cell_row[at][mine]],
                    dtype=np.int64)
    cols = np.array([columns.index(s.col_keys[int(c)][1]) for c in s.cell_col[at][mine]],
                    dtype=np.int64)
    grid = np.full((len(configs), table.rows, len(columns)), np.nan)
    grid[:, rows, cols] = configs[:, mine]
    return columns, grid[read, np.arange(read.shape[0])[:, None, None]]
