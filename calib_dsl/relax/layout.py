"""What the relaxations derive from a program whatever the box: its unknowns (the LP's
variables), which unknowns each group depends on, and the rows that define each temporary.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_dsl.ir.program import Program, derived
from calib_dsl.ir.rows import tiled_mask
from calib_dsl.ir.status import UNKNOWNS


def independents(prog: Program) -> np.ndarray:
    """The slots of the declared unknowns: the LP's variables."""
    s = prog.slots
    return np.array(sorted({i for i in s.declared if s.kinds[i] in UNKNOWNS}),
                    dtype=np.int64)


def group_unknowns(prog: Program, ind: np.ndarray) -> list[np.ndarray]:
    """For each group, the unknowns (column numbers) that some argument of it depends on."""
    n = len(ind)
    dep = np.zeros((len(prog.slots.names), n), dtype=bool)
    dep[ind, np.arange(n)] = True
    out = []
    for g in prog.groups:
        rows = np.zeros((g.out.shape[0], n), dtype=bool)
        for col in g.args.T:
            rows |= dep[col]
        for j in range(g.out.shape[1]):
            dep[g.out[:, j]] |= rows
        out.append(np.flatnonzero(rows.any(axis=0)))
    return out


@dataclass
class Layout:
    """What every forward pass over a program needs, whatever the box: worked out once per
    program (the tight strategy relaxes the same program dozens of times)."""

    ind: np.ndarray  # the declared unknowns' slots
    temp: np.ndarray  # bool per slot
    const: np.ndarray
    defining: list[np.ndarray]  # _defining_masks
    used: list[np.ndarray]  # group_unknowns
    # The passes keep their per-slot arrays of rows (gradients) in this row order: each
    # group's defining outputs take the next rows, so a group stores its results as one
    # slice (a fancy store cost a fifth of a relaxation); the other slots come last.
    pos: np.ndarray  # the row of each slot
    order: np.ndarray  # the slot of each row
    blocks: list[list[tuple[int, int]]]  # per group and output: its defining rows' slice
    # per group and argument column: its rows, and the (rows, used unknowns) pair of index
    # arrays its gradients are taken at (made once: a pass takes them many times)
    args: list[list[np.ndarray]]
    takes: list[list[tuple]]


def layout(prog: Program, ind: np.ndarray | None = None) -> Layout:
    """The program's layout for the unknowns `ind` (its declared unknowns if None; made once
    per program for those, anew for others)."""
    mine = independents(prog)
    if ind is not None and not np.array_equal(ind, mine):
        if not len(ind):  # (a pass without gradients, relax/chunked.py: made once too)
            return derived(prog, "layout without unknowns", lambda: _layout(prog, ind))
        return _layout(prog, ind)
    return derived(prog, "layout", lambda: _layout(prog, mine))


@dataclass(frozen=True)
class Definitions:
    """Which slots are temporaries and constants, and which rows of each group define their
    output (the rest are constraints): what a plain forward pass needs (certify_point.py),
    without the gradients' layout."""

    temp: np.ndarray
    const: np.ndarray
    defining: list[np.ndarray]


def definitions(prog: Program) -> Definitions:
    """The program's Definitions (made once per program)."""
    return derived(prog, "definitions", lambda: _definitions(prog))


def _definitions(prog: Program) -> Definitions:
    temp = tiled_mask(prog.slots.kinds, ("temp",))
    return Definitions(temp, tiled_mask(prog.slots.kinds, ("const",)),
                       _defining_masks(prog, temp))


def _layout(prog: Program, ind: np.ndarray) -> Layout:
    d = definitions(prog)
    temp, const, defining = d.temp, d.const, d.defining
    used = group_unknowns(prog, ind)
    first: list[np.ndarray] = []
    blocks: list[list[tuple[int, int]]] = []
    at = 0
    for g, m in zip(prog.groups, defining, strict=True):
        blocks.append([])
        for j in range(g.out.shape[1]):
            out = g.out[m[:, j], j]  # (no repeats: a slot is defined once)
            first.append(out)
            blocks[-1].append((at, at + len(out)))
            at += len(out)
    placed = np.concatenate([np.zeros(0, np.int64), *first]).astype(np.int64)
    rest = np.setdiff1d(np.arange(len(temp)), placed)
    order = np.concatenate([placed, rest])
    pos = np.empty(len(temp), dtype=np.int64)
    pos[order] = np.arange(len(temp))
    args = [[pos[c] for c in g.args.T] for g in prog.groups]
    takes = [[(r, u) for r in rows] for rows, u in zip(args, used, strict=True)]
    return Layout(ind, temp, const, defining, used, pos, order, blocks, args,
                  takes)


def measured_cells(prog: Program) -> int:
    """How many LP columns `relax` with cell_variables may need: the measured values with an
    error (one column each at most; fewer when no row uses one)."""
    s = prog.slots
    return int(np.sum(cells(prog, tiled_mask(s.kinds, ("const",)), s.lo, s.hi)))


def row_key(group: int, output: int, at: np.ndarray) -> np.ndarray:
    """Constraint rows as one id each (int64), the same in every pass over a program: the
    rows `at` of output `output` of group `group` (a group past the last: the capped
    temporaries, `at` their slots)."""
    return (np.int64(group) << 40) + (np.int64(output) << 32) + np.asarray(at, np.int64)


def cells(prog: Program, const: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The slots that are measured values with an error (an LP column each, at most)."""
    rows = prog.slots.cell_row
    if rows is None:
        return np.zeros(len(lo), dtype=bool)
    return (rows >= 0) & const & (hi > lo) & np.isfinite(lo) & np.isfinite(hi)


def _defining_masks(prog: Program, temp: np.ndarray) -> list[np.ndarray]:
    """Per group, (rows, outputs) bool: which rows define their output temporary (its first
    output in program order); the others are constraints."""
    defined = np.zeros(len(temp), dtype=bool)
    masks = []
    for g in prog.groups:
        m = np.zeros(g.out.shape, dtype=bool)
        for j in range(g.out.shape[1]):
            col = g.out[:, j]
            _, first = np.unique(col, return_index=True)
            firsts = np.zeros(len(col), dtype=bool)
            firsts[first] = True
            m[:, j] = temp[col] & ~defined[col] & firsts
            defined[col[m[:, j]]] = True
        masks.append(m)
    return masks
