"""A program whose loop over a table's rows was compiled once, in chunks of rows.

The relaxations and the point evaluations keep, per slot, a gradient or a Taylor model in
every unknown: over 10,000 rows of a robot that is gigabytes at once. Every row's part of
such a program is a copy of the first row's (compile/replicate.py), and a row's constraints
read only the shared slots and the row's own, so the same passes can run over a few hundred
rows at a time, the shared part again with each, and keep only what each chunk yields.

The program of `size` rows is a prefix of the whole program: its shared slots, then the
first `size` rows' blocks, and each group's entries up to the end of those rows (the groups
are laid out shared entries first, then row after row: replicate.tile_groups). It is built
once (with what the passes derive from it), and a chunk is that program on the box of some
`size` rows, read off the whole box (two slices when the rows are contiguous). The rows
are shared evenly among as few chunks as `max_slots` allows (a multiple of the threads
that run them); a last, shorter chunk repeats
its last row to fill the size, and the copies' results are dropped: one program serves
every chunk. Slot numbers and table-row ids (`Slots.cell_row`) of a
chunk map back to the whole program's by its rows.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace

import numpy as np

from calib_dsl.ir.primitives import Slots
from calib_dsl.ir.program import Group, Program, derived
from calib_dsl.ir.rows import RowLayout, Tiled
from calib_dsl.settings import LPSettings

# the threads a chunked pass shares its chunks among (relax/chunked.in_threads: the LPs')
THREADS = LPSettings.workers


@dataclass(frozen=True)
class Chunk:
    """Some rows of a program (`rows`: loop row indices, increasing): `prog` is the program
    of that many rows, whose slots and table row ids map to the whole program's by
    `slots` and `row_ids`."""

    prog: Program
    rows: np.ndarray
    layout: RowLayout  # of the whole program
    first: bool  # the first chunk: the only one whose shared-only rows are kept
    real: int  # the rows before the copies of the last that fill a short chunk

    @property
    def span(self) -> slice | None:
        """The rows as a slice when they are contiguous (a view, not a copy, reads them). (A
        short chunk's copies of its last row can make up for a gap in the count: each step
        is checked.)"""
        a, b = int(self.rows[0]), int(self.rows[-1]) + 1
        contiguous = b - a == len(self.rows) and bool(np.all(np.diff(self.rows) == 1))
        return slice(a, b) if contiguous else None

    def box(self, x: np.ndarray) -> np.ndarray:
        """The whole program's per-slot array x, read for this chunk's slots."""
        lay = self.layout
        blocks = x[lay.shared: lay.shared + len(lay.rows) * lay.width].reshape(-1, lay.width)
        span = self.span
        part = blocks[span] if span is not None else blocks[self.rows]
        return np.concatenate([x[:lay.shared], part.ravel()])

    def slots(self, local: np.ndarray) -> np.ndarray:
        """This chunk's slot numbers as the whole program's (negative ones unchanged)."""
        lay = self.layout
        r, j = np.divmod(np.maximum(local - lay.shared, 0), lay.width)
        moved = lay.shared + self.rows[np.minimum(r, len(self.rows) - 1)] * lay.width + j
        return np.where(local >= lay.shared, moved, local)

    def prims(self, local: np.ndarray) -> np.ndarray:
        """This chunk's primitive numbers as the whole program's."""
        lay = self.layout
        r, j = np.divmod(np.maximum(local - lay.shared_prims, 0), max(lay.count, 1))
        moved = lay.shared_prims + self.rows[np.minimum(r, len(self.rows) - 1)] * lay.count + j
        return np.where(local >= lay.shared_prims, moved, local)

    def row_ids(self, local: np.ndarray) -> np.ndarray:
        """Table row ids (Slots.cell_row, owners) of this chunk as the whole program's: a
        loop row's id is its row's; a shared table row's and the markers (negative) are
        unchanged."""
        per = len(self.layout.tables)
        mine = (local >= 0) & (local < len(self.rows) * per)
        r, t = np.divmod(np.where(mine, local, 0), per)
        return np.where(mine, self.rows[r] * per + t, local)

    def kept(self, targets: np.ndarray) -> np.ndarray:
        """Which constraint rows (by their target slots, local) this chunk contributes: not a
        copy's that fills the chunk, and the shared part's only in the first chunk (a
        shared slot is defined from shared slots only, so every chunk has those rows)."""
        lay = self.layout
        shared = targets < lay.shared
        row = (targets - lay.shared) // max(lay.width, 1)
        return np.where(shared, self.first, row < self.real)


def chunked(prog: Program, max_slots: int, rows: np.ndarray | None = None
            ) -> list[Chunk] | None:
    """The program's loop rows `rows` (all if None) in chunks of about `max_slots` slots
    each, or None when the program has no loop compiled once, or all of it fits in one
    chunk (then passes run on the whole program)."""
    lay = prog.rows
    if lay is None:
        return None
    if rows is None:
        if len(prog.slots.lo) <= max_slots:
            return None
        rows = np.arange(len(lay.rows))
    if len(rows) == 0:
        raise ValueError("no rows to take")
    most = min(max(1, (max_slots - lay.shared) // max(lay.width, 1)), len(rows))
    # as many chunks as the largest size needs, rounded up to a multiple of the threads that
    # share a pass's chunks (none idle in the last turn), of even sizes: a short last chunk
    # is padded with copies of its last row, so it costs as much as a full one
    count = -(-len(rows) // most)
    if count > 1:
        count = min(-(-count // THREADS) * THREADS, len(rows))
    ends = [len(rows) * k // count for k in range(count + 1)]  # (sizes differ by one at most)
    size = max(b - a for a, b in itertools.pairwise(ends))
    whole = prefix(prog, size)
    out = []
    for a, b in itertools.pairwise(ends):
        part = np.asarray(rows[a:b], dtype=np.int64)
        real = len(part)
        part = np.concatenate([part, np.full(size - real, part[-1], dtype=np.int64)])
        out.append(Chunk(whole, part, lay, a == 0, real))
    return out


def loop_rows(prog: Program) -> int:
    """The rows of the program's loop compiled once (0 without one)."""
    return len(prog.rows.rows) if prog.rows is not None else 0


def spread_rows(prog: Program, size: int) -> np.ndarray | None:
    """`size` rows of the program's loop compiled once, evenly spread (loop row indices),
    when it has more than twice as many; else None (a sample would save little)."""
    n = loop_rows(prog)
    if n <= 2 * size:
        return None
    return np.unique(np.linspace(0, n - 1, size).astype(np.int64))


def start_rows(prog: Program, size: int) -> np.ndarray | None:
    """`size` rows of the program's loop compiled once, evenly spread (loop row indices; all
    of them when it has no more), or None without such a loop."""
    n = loop_rows(prog)
    if n == 0:
        return None
    return np.unique(np.linspace(0, n - 1, min(size, n)).astype(np.int64))


def prefix(prog: Program, rows: int) -> Program:
    """The program of the first `rows` rows of the loop (made once per program and size)."""
    return derived(prog, f"rows prefix {rows}", lambda: _prefix(prog, rows))


def _prefix(prog: Program, rows: int) -> Program:
    lay = prog.rows
    assert lay is not None and 0 < rows <= len(lay.rows)
    n_slots = lay.shared + rows * lay.width
    n_prims = lay.shared_prims + rows * lay.count
    small = replace(lay, rows=lay.rows[:rows])
    return Program(prog.source, prog.formulation, _slots(prog.slots, small, n_slots),
                   _tiled(prog.primitives, rows), [_group(g, n_prims) for g in prog.groups],
                   prog.true_values, prog.domains, prog.priors, prog.centred,
                   prog.true_stated, small, prog.units, prog.tables,
                   prog.sources)


def _group(g: Group, n_prims: int) -> Group:
    # shared entries first, then row after row: the prefix that ends with the last row kept
    k = int(np.count_nonzero(g.prim < n_prims))
    assert bool(np.all(g.prim[:k] < n_prims))
    return Group(g.op, g.level, g.out[:k], g.args[:k],
                 None if g.param is None else g.param[:k], g.prim[:k], g.out_unique,
                 g.args_unique)


def _tiled(x: object, rows: int) -> Tiled:
    """A tiled list (of a program whose loop was compiled once) for its first `rows` rows."""
    assert isinstance(x, Tiled)
    return Tiled(x.shared, x.template, rows, x.render)


def _slots(s: Slots, lay: RowLayout, n: int) -> Slots:
    assert isinstance(s.names, Tiled) and isinstance(s.kinds, Tiled)
    assert isinstance(s.origin, Tiled)
    rows = len(lay.rows)
    sides = None if s.measured_sides is None else \
        {k: v for k, v in s.measured_sides.items() if k < n}
    return Slots(_tiled(s.names, rows), _tiled(s.kinds, rows), s.lo[:n].copy(),
                 s.hi[:n].copy(), _tiled(s.origin, rows), list(s.declared),
                 list(s.declared_names),
                 None if s.cell_row is None else s.cell_row[:n].copy(),
                 None if s.cell_col is None else s.cell_col[:n].copy(),
                 s.row_keys, s.col_keys, sides, set(s.capped_by_rows),
                 {k for k in s.implied if k < n})
