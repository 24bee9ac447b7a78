"""A loop compiled once (elaborate/batching.py): the program of its two template rows becomes
the program of all its rows, built from arrays.

The two template rows' parts of the program are found by following each row's cells forward
through the primitives; they must be copies of each other (same operations on corresponding
slots, same domains but for the cells' and the measured values') and touch nothing of any
other row, or the loop is unrolled instead (`NotBatchable`). The first row's part is then
the template: row r's slots and primitives are its copy, shifted by r blocks, with row r's
cells (ir/rows.py lays this out). The groups the propagator runs are the template's groups
with their index arrays tiled, so the program equals the unrolled one up to slot numbering.
"""

from __future__ import annotations

import numpy as np

from calib_dsl.ir.model import Model, RowBatch
from calib_dsl.ir.primitives import Primitive, PrimitiveArrays, Slots, format_const
from calib_dsl.ir.program import Group
from calib_dsl.ir.rows import RowLayout, Tiled
from calib_dsl.ir.status import SlotKind

NONE, MIXED = -1, -2


class NotBatchable(Exception):
    """The two template rows are not copies of each other: unroll the loop."""


def replicate(model: Model, slots: Slots, prims: list[Primitive], arrays: PrimitiveArrays
              ) -> tuple[Slots, Tiled[Primitive], PrimitiveArrays, RowLayout]:
    """The program of every row of `model.batch`: its slots, its primitives, the template's
    primitives as arrays (shared ones, then the first row's: group them, then
    `tile_groups`), and the layout; NotBatchable when the template rows are no copies."""
    batch = model.batch
    assert batch is not None
    dep, pc = _copies(batch, slots, arrays)
    s0, p0, shared_slots, shared_prims = _check_copies(batch, slots, arrays, dep, pc)
    n, width = len(batch.rows), len(s0)
    new = np.full(len(slots.lo) + 1, -1, dtype=np.int64)  # old slot -> new (index -1: -1)
    new[shared_slots] = np.arange(len(shared_slots))
    new[s0] = len(shared_slots) + np.arange(width)
    keep = np.concatenate([shared_prims, p0])
    small = _mapped_arrays(arrays, keep, new)
    tables = tuple(dict.fromkeys(t for t, _ in batch.cells))
    layout = RowLayout(np.array(batch.rows, dtype=np.int64), len(shared_slots), width,
                       len(shared_prims), len(p0), tables, batch.loc)
    out_slots = _slots(batch, slots, dep, shared_slots, s0, new, layout)
    _name_temporaries(out_slots, small, layout)
    template = [Primitive(small.op[i], _tuple(small.out[i]), _tuple(small.args[i], small.arity[i]),
                          small.param[i], prims[int(keep[i])].loc, int(small.level[i]))
                for i in range(len(keep))]
    primitives: Tiled[Primitive] = Tiled(template[:len(shared_prims)],
                                         template[len(shared_prims):], n, _RowPrimitive(layout))
    return out_slots, primitives, small, layout


# -- the two template rows ---------------------------------------------------------------------
def _combine(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.where(a == NONE, b, np.where((b == NONE) | (a == b), a, MIXED))


def _copies(batch: RowBatch, s: Slots, a: PrimitiveArrays) -> tuple[np.ndarray, np.ndarray]:
    """Per slot and per primitive: which template row (0, 1) it belongs to, NONE (shared) or
    MIXED (both)."""
    m = len(s.lo)
    keys = s.row_keys or []
    tables = {t for t, _ in batch.cells}
    copy_of = np.array([batch.template.index(k) if t in tables and k in batch.template
                        else NONE for t, k in keys] + [NONE], dtype=np.int64)
    dep = np.full(m + 1, NONE, dtype=np.int64)  # slot m: an absent argument (-1)
    if s.cell_row is not None:
        dep[:m] = np.where(s.cell_row >= 0, copy_of[np.where(s.cell_row >= 0, s.cell_row, -1)],
                           NONE)
    for slot, (row, _) in (s.measured_sides or {}).items():
        dep[slot] = _combine(dep[slot:slot + 1], copy_of[row:row + 1])[0]
    for slot in s.capped_by_rows:  # compared with several rows' values: shared by them
        dep[slot] = MIXED
    out = np.where(a.out >= 0, a.out, m)
    args = np.where(a.args >= 0, a.args, m)
    order = np.argsort(a.level, kind="stable")
    cuts = np.flatnonzero(np.diff(a.level[order])) + 1
    for _ in range(8):  # merged slots can feed an earlier level: sweep until stable
        before = dep.copy()
        for idx in np.split(order, cuts):
            d = _combine(_combine(dep[args[idx, 0]], dep[args[idx, 1]]), dep[args[idx, 2]])
            for j in range(2):
                d = _combine(d, dep[out[idx, j]])
            for j in range(2):
                _reduce(dep, out[idx, j], d)
            dep[m] = NONE
        if np.array_equal(before, dep):
            break
    else:
        raise NotBatchable("the rows' parts do not settle")
    pc = np.full(len(a.level), NONE, dtype=np.int64)
    for col in (*out.T, *args.T):
        pc = _combine(pc, dep[col])
    return dep[:m], pc


def _reduce(dep: np.ndarray, at: np.ndarray, d: np.ndarray) -> None:
    """dep[at] combined with every d written there (several primitives may write a slot)."""
    lo = dep.copy()
    hi = dep.copy()
    np.minimum.at(lo, at, d)
    np.maximum.at(hi, at, d)
    seen = np.zeros(len(dep), dtype=bool)
    seen[at] = True
    # values are MIXED (-2), NONE (-1), 0, 1: one row when the highest is a row and the
    # lowest is that row or NONE
    one = (hi >= 0) & ((lo == hi) | (lo == NONE))
    dep[seen] = np.where(lo[seen] == MIXED, MIXED, np.where(one[seen], hi[seen],
                                                              np.where(hi[seen] == NONE,
                                                                       NONE, MIXED)))


def _check_copies(batch: RowBatch, s: Slots, a: PrimitiveArrays, dep: np.ndarray,
                  pc: np.ndarray) -> tuple[np.ndarray, ...]:
    if (dep == MIXED).any() or (pc == MIXED).any():
        raise NotBatchable("a row's part of the program meets another row's")
    s0, s1 = np.flatnonzero(dep == 0), np.flatnonzero(dep == 1)
    p0, p1 = np.flatnonzero(pc == 0), np.flatnonzero(pc == 1)
    if len(s0) != len(s1) or len(p0) != len(p1) or not len(p0):
        raise NotBatchable("the template rows differ in size")
    to1 = np.arange(len(s.lo) + 1)
    to1[s0] = s1
    to1[-1] = -1
    if any(a.op[i] != a.op[j] or a.param[i] != a.param[j] for i, j in
           zip(p0.tolist(), p1.tolist(), strict=True)) \
            or not np.array_equal(a.level[p0], a.level[p1]) \
            or not np.array_equal(to1[a.out[p0]], a.out[p1]) \
            or not np.array_equal(_sorted_commutative(a, p0, to1[a.args[p0]]),
                                  _sorted_commutative(a, p1, a.args[p1])):
        raise NotBatchable("the template rows' primitives differ")
    kinds = s.kinds
    if any(kinds[i] != kinds[j] for i, j in zip(s0.tolist(), s1.tolist(), strict=True)):
        raise NotBatchable("the template rows' slots differ")
    for copy, slots_c in enumerate((s0, s1)):
        lo, hi = _row_bounds(batch, s, slots_c, np.array([batch.template[copy]]))
        if not (np.array_equal(lo[0], s.lo[slots_c]) and np.array_equal(hi[0], s.hi[slots_c])):
            raise NotBatchable("a row slot's domain is not its row's")
    return s0, p0, np.flatnonzero(dep == NONE), np.flatnonzero(pc == NONE)


def _sorted_commutative(a: PrimitiveArrays, prims: np.ndarray, args: np.ndarray) -> np.ndarray:
    """The arguments, those of a + b and a * b in increasing order (the DAG orders them by
    node, which differs from row to row)."""
    swap = np.array([a.op[i] in ("add", "mul") for i in prims.tolist()], dtype=bool)
    swap &= args[:, 0] > args[:, 1]
    out = args.copy()
    out[swap, 0], out[swap, 1] = args[swap, 1], args[swap, 0]
    return out


# -- the program of all rows ---------------------------------------------------------------
def _measured(s: Slots, slots: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per slot: the table row id and column id of the cell that gives its domain (a
    constant read from a table, or a slot capped by a measured value); -1 for neither."""
    rows = np.full(len(slots), -1, dtype=np.int64)
    cols = np.full(len(slots), -1, dtype=np.int64)
    if s.cell_row is not None and s.cell_col is not None:
        cell = s.cell_row[slots] >= 0
        const = np.array([s.kinds[int(i)] == SlotKind.CONST for i in slots], dtype=bool)
        rows = np.where(cell & const, s.cell_row[slots], rows)
        cols = np.where(cell & const, s.cell_col[slots], cols)
    sides = s.measured_sides or {}
    for j, slot in enumerate(slots.tolist()):
        if slot in sides:
            rows[j], cols[j] = sides[slot]
    return rows, cols


def _row_bounds(batch: RowBatch, s: Slots, template: np.ndarray, rows: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """(len(rows), width) initial domains of the template's row slots in each of `rows`:
    the template's, but for the cells and measured values, which are the row's."""
    lo = np.tile(s.lo[template], (len(rows), 1))
    hi = np.tile(s.hi[template], (len(rows), 1))
    row_ids, col_ids = _measured(s, template)
    for j in np.flatnonzero(row_ids >= 0).tolist():
        table = (s.row_keys or [])[row_ids[j]][0]
        column = (s.col_keys or [])[col_ids[j]]
        if column[0] != table or column not in batch.cells:
            continue  # a cell of another table: the same in every row (checked)
        clo, chi = batch.cells[column]
        lo[:, j], hi[:, j] = clo[rows - 1], chi[rows - 1]
    return lo, hi


def _slots(batch: RowBatch, s: Slots, dep: np.ndarray, shared: np.ndarray, s0: np.ndarray,
           new: np.ndarray, layout: RowLayout) -> Slots:
    n, width = len(batch.rows), len(s0)
    ks = layout.rows
    lo_r, hi_r = _row_bounds(batch, s, s0, ks)
    lo = np.concatenate([s.lo[shared], lo_r.ravel()])
    hi = np.concatenate([s.hi[shared], hi_r.ravel()])
    # table rows: the loop's first (one id per table and row k), then any other
    keys = s.row_keys or []
    batch_keys = [(t, int(k)) for k in ks.tolist() for t in layout.tables]
    at = {key: i for i, key in enumerate(batch_keys)}
    for key in keys:
        at.setdefault(key, len(at))
    row_keys = list(at)
    old_to_new = np.array([at[key] for key in keys] + [-1], dtype=np.int64)
    t_of = np.array([layout.tables.index(t) if t in layout.tables else -1 for t, _ in keys]
                    + [-1], dtype=np.int64)
    cell_row = cell_col = None
    if s.cell_row is not None and s.cell_col is not None:
        shared_rows = np.where(s.cell_row[shared] >= 0, old_to_new[s.cell_row[shared]],
                               s.cell_row[shared])
        t_rows = s.cell_row[s0]
        per_row = np.where(t_rows >= 0, t_of[np.where(t_rows >= 0, t_rows, -1)], -1)
        row_block = np.where(per_row >= 0,
                             np.arange(n)[:, None] * len(layout.tables) + per_row[None, :],
                             t_rows[None, :])
        cell_row = np.concatenate([shared_rows, row_block.ravel()])
        cell_col = np.concatenate([s.cell_col[shared], np.tile(s.cell_col[s0], n)])
    sides: dict[int, tuple[int, int]] = {}
    for slot, (row, col) in (s.measured_sides or {}).items():
        if dep[slot] < 0:
            sides[int(new[slot])] = (int(old_to_new[row]), col)
        elif dep[slot] == 0:
            j, ti = int(new[slot]) - layout.shared, int(t_of[row])
            base = layout.shared + j
            for r in range(n):
                sides[base + r * width] = (r * len(layout.tables) + ti, col)
    implied = set()
    for slot in s.implied:  # the template's and the shared ones (the second row's: copies)
        if dep[slot] < 0:
            implied.add(int(new[slot]))
        elif dep[slot] == 0:
            implied.update(int(new[slot]) + r * width for r in range(n))
    names_t = [s.names[i] for i in s0.tolist()]
    kinds_t = [s.kinds[i] for i in s0.tolist()]
    return Slots(
        Tiled([s.names[i] for i in shared.tolist()], names_t, n,
              _RowSlotName(layout, kinds_t, lo, hi)),
        Tiled([s.kinds[i] for i in shared.tolist()], kinds_t, n),
        lo, hi,
        Tiled([s.origin[i] for i in shared.tolist()], [s.origin[i] for i in s0.tolist()], n),
        [int(new[i]) for i in s.declared], list(s.declared_names),
        cell_row, cell_col, row_keys, list(s.col_keys or []), sides, implied=implied)


class _RowPrimitive:
    """Row r's copy of a template primitive (a class, not a closure: programs are pickled
    for child processes and Dask workers)."""

    def __init__(self, layout: RowLayout) -> None:
        self.layout = layout

    def __call__(self, p: Primitive, r: int, _j: int) -> Primitive:
        return p._replace(out=self.layout.shift(p.out, r), args=self.layout.shift(p.args, r))


class _RowSlotName:
    """Row r's name of a template slot: a constant's value, else `t7@k` (k: the row)."""

    def __init__(self, layout: RowLayout, kinds: list[str], lo: np.ndarray,
                 hi: np.ndarray) -> None:
        self.layout, self.kinds, self.lo, self.hi = layout, kinds, lo, hi

    def __call__(self, name: str, r: int, j: int) -> str:
        if self.kinds[j] == SlotKind.CONST:
            i = self.layout.shared + r * self.layout.width + j
            return format_const(float(self.lo[i]), float(self.hi[i]))
        return f"{name}@{self.layout.rows[r]}"


def _mapped_arrays(a: PrimitiveArrays, keep: np.ndarray, new: np.ndarray) -> PrimitiveArrays:
    ks = keep.tolist()
    return PrimitiveArrays([a.op[i] for i in ks], new[a.out[keep]], new[a.args[keep]],
                           a.arity[keep], [a.param[i] for i in ks], a.level[keep])


def _tuple(row: np.ndarray, arity: int | None = None) -> tuple[int, ...]:
    values = [int(v) for v in row.tolist()]
    return tuple(values[:arity]) if arity is not None else tuple(v for v in values if v >= 0)


def _name_temporaries(s: Slots, a: PrimitiveArrays, layout: RowLayout) -> None:
    """t1, t2, ... for the template's temporaries in the order its primitives output them
    (row copies read `t7@k`)."""
    assert isinstance(s.names, Tiled) and isinstance(s.kinds, Tiled)
    count = 0
    seen: set[int] = set()
    for slot in a.out.ravel().tolist():
        if slot < 0 or slot in seen:
            continue
        seen.add(slot)
        row = layout.row_slot(slot)
        kind = s.kinds.shared[slot] if row is None else s.kinds.template[row[1]]
        if kind != SlotKind.TEMP:
            continue
        count += 1
        if row is None:
            s.names.shared[slot] = f"t{count}"
        else:
            s.names.template[row[1]] = f"t{count}"


def tile_groups(groups: list[Group], layout: RowLayout) -> list[Group]:
    """Each group's row part copied for every row (slots and primitive indices shifted)."""
    n = len(layout.rows)
    slot_step = (np.arange(n, dtype=np.int64) * layout.width)[:, None, None]
    prim_step = (np.arange(n, dtype=np.int64) * layout.count)[:, None]
    out = []
    for g in groups:
        row = g.prim >= layout.shared_prims
        go, ga = (_tile(x, row, slot_step, layout.shared) for x in (g.out, g.args))
        prim = np.concatenate([g.prim[~row], (g.prim[row][None] + prim_step).ravel()])
        param = None if g.param is None else \
            np.concatenate([g.param[~row], np.tile(g.param[row], n)])
        out.append(Group(g.op, g.level, go, ga, param, prim,
                         tuple(_unique(c, row, layout, n) for c in g.out.T),
                         tuple(_unique(c, row, layout, n) for c in g.args.T)))
    return out


def _tile(x: np.ndarray, row: np.ndarray, step: np.ndarray, shared: int) -> np.ndarray:
    """x's shared entries, then its row entries once per row (row slots moved by `step`)."""
    part = x[row]
    moved = part[None] + step * (part >= shared)[None]
    return np.concatenate([x[~row], moved.reshape(-1, x.shape[1])])


def _unique(column: np.ndarray, row: np.ndarray, layout: RowLayout, n: int) -> bool:
    """No slot twice in the tiled column: none in the template, and the row part reads no
    shared slot (which every row's copy would read again)."""
    s = np.sort(column)
    once = bool((s[1:] != s[:-1]).all())
    return once and (n == 1 or bool((column[row] >= layout.shared).all()))
