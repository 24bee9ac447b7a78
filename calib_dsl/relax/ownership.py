"""Which data row (a configuration of a table: its cells, `Slots.cell_row`) each constraint
row of the program depends on, for solving with outliers (outliers/solve.py): a row that
reads a cell of configuration k, or compares with one of its measured values, holds only if
configuration k is no outlier.

Unlike the relaxations' `owner` (relax/evaluation.py), which follows only the cells that carry
an error (LP columns), this follows every cell, exact ones too, and the measured values that
cap a slot's domain (`Slots.measured_sides`). A row that depends on several data rows is
marked MIXED: solving with outliers drops it (dropping a row only loses tightness).
"""

from __future__ import annotations

import numpy as np

from calib_dsl.ir.program import Program
from calib_dsl.ir.rows import tiled_mask
from calib_dsl.relax.layout import layout

NONE, MIXED = -1, -2


def combine(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The data row of something that depends on both: NONE, one row id, or MIXED."""
    return np.where(a == NONE, b, np.where((b == NONE) | (a == b), a, MIXED))


def value_rows(prog: Program, ind: np.ndarray, only: np.ndarray | None = None) -> np.ndarray:
    """Per slot, the data row its value depends on (forward through the defining primitives;
    a cell shared by several rows, cell_row -2, is MIXED already); with `only`, through the
    cells of that mask only."""
    s = prog.slots
    n = len(s.lo)
    dep = (np.where(s.cell_row == -2, MIXED, np.maximum(s.cell_row, NONE))
           if s.cell_row is not None else np.full(n, NONE))
    if only is not None:
        dep = np.where(only, dep, NONE)
    dep = np.concatenate([dep, [NONE]])  # index -1 (an absent argument): no data row
    lay = layout(prog, ind)
    for g, mask in zip(prog.groups, lay.defining, strict=True):
        rows = dep[g.args[:, 0]]
        for j in range(1, g.args.shape[1]):
            rows = combine(rows, dep[g.args[:, j]])
        for j in range(g.out.shape[1]):
            d = mask[:, j]
            dep[g.out[d, j]] = rows[d]
    return dep[:n]


def domain_rows(prog: Program) -> np.ndarray:
    """Per slot, the data row its domain comes from: a measured cell's (a constant read from
    a table, or a slot capped by a measured value); NONE for the others."""
    s = prog.slots
    n = len(s.lo)
    dep = np.full(n, NONE)
    if s.cell_row is not None:
        const = tiled_mask(s.kinds, ("const", "data"))
        dep = np.where(const & (s.cell_row >= 0), s.cell_row, dep)
        dep = np.where(const & (s.cell_row == -2), MIXED, dep)
    for slot, (row, _) in (s.measured_sides or {}).items():
        dep[slot] = combine(dep[slot:slot + 1], np.array([row]))[0]
    return dep


def row_owners(prog: Program, ind: np.ndarray, sources: list[np.ndarray],
               targets: list[np.ndarray]) -> np.ndarray:
    """The data row of each constraint row of an Evaluation (its `sources` and target slots,
    by rows as in its `rows`): that of the computed side's arguments combined with the
    target's value and domain."""
    if not sources:
        return np.zeros(0, dtype=np.int64)
    value = np.concatenate([value_rows(prog, ind), [NONE]])
    domain = domain_rows(prog)
    out = []
    for args, slots in zip(sources, targets, strict=True):
        rows = combine(value[slots], domain[slots])
        for j in range(args.shape[1]):
            rows = combine(rows, value[args[:, j]])
        out.append(rows)
    return np.concatenate(out).astype(np.int64)
