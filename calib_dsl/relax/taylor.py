"""Second-order Taylor models of every slot of a program over a box (rigorous).

On a wide box the first-order (mean-value) relaxation of `linearize` pays the model's whole
curvature in its right-hand sides; on wide domains that can be a large share of the
first-order range, and then no linear relaxation contracts (docs/decisions/01). A
second-order model keeps the curvature as coefficients and leaves only the third-order
terms to a remainder.

Each unknown p_i is written p_i = c_i + w_i t_i with t_i in [-1, 1] (c the box's midpoint, w
its half-width rounded up, so the t-box covers the p-box in exact arithmetic). A *model* of a
slot is a polynomial in t of degree 2 with float coefficients plus a remainder radius r:

    for every t in [-1, 1]^n:   slot value  in  c0 + c1.t + sum_k c2_k m_k(t) + [-r, r]

where m_k(t) = t_i t_j (i <= j). Every operation truncates its product terms to degree 2 and
bounds what it drops (|t_i| <= 1 makes every monomial's magnitude at most 1), and every
floating-point rounding of a coefficient goes into r as well, so the enclosure holds in exact
arithmetic. Models are computed forward through the flat program, one numpy call per group
and operation, like the propagator. Supported primitives: neg, add, sub, mul, sqr, sin, cos,
rot (the matrix and rotation formulations of the robot layer); a program with another
primitive has no model (`None`), and the strategies fall back to first order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_dsl.compile.chunks import Chunk, chunked
from calib_dsl.ir.program import Program, derived
from calib_dsl.relax.chunked import in_threads
from calib_dsl.relax.layout import Layout, independents, layout, row_key
from calib_dsl.relax.models import SUPPORTED, Models, Pairs, add, apply, constant, up
from calib_dsl.settings import Settings

# (module attributes, the settings' declared values: tests make chunks and memory small)
CHUNK_SLOTS = Settings.chunk_slots
MAX_TABLE_BYTES = Settings.max_table_bytes


@dataclass
class Constraints:
    """Each constraint row as `model in [lo, hi]`: the row's model and its target interval,
    and the slot it compares with (its target)."""

    models: Models
    lo: np.ndarray
    hi: np.ndarray
    slots: np.ndarray
    # each row's place in the program (row_key; None for a program expanded in chunks):
    # how the rows of another pass over the same program are matched with these
    keys: np.ndarray | None = None
    # each row's constraint in the whole program's numbering (constraint_ids): the same id
    # in every expansion of the program, chunked or not, whichever of its rows it takes
    ids: np.ndarray | None = None

    def take(self, pick: np.ndarray) -> Constraints:
        return Constraints(self.models.take(pick), self.lo[pick], self.hi[pick],
                           self.slots[pick], None if self.keys is None else self.keys[pick],
                           None if self.ids is None else self.ids[pick])


@dataclass
class Expansion:
    center: np.ndarray  # c (the unknowns' midpoints)
    half: np.ndarray  # w (half-widths, rounded up): p = c + w t
    pairs: Pairs
    rows: Constraints
    kept: np.ndarray | None = None  # the products given LP columns (set by quadratic.py)
    # the rows' coefficients of (t, the products), one column a row, the rows' models' c1
    # and c2 views of it (expand's `by_terms`, where it joined chunks)
    coef: np.ndarray | None = None


def supported(prog: Program) -> bool:
    return all(g.op in SUPPORTED for g in prog.groups)


def expand(prog: Program, lo: np.ndarray, hi: np.ndarray,
           rows: np.ndarray | None = None, by_terms: bool = False) -> Expansion | None:
    """Second-order models of every constraint row over the box [lo, hi] (the unknowns'
    entries; the other slots' entries give the constants' and the targets' ranges); of the
    loop's rows `rows` only, if given. None when a primitive has no model, an unknown is
    unbounded, or the models would not fit in MAX_TABLE_BYTES (settings.max_table_bytes). A large
    program whose rows were compiled once is expanded a chunk of rows at a time
    (compile/chunks.py): the models live for one chunk; the rows' models are kept (with
    `by_terms`, in the Expansion's `coef`, one column a row: what a product of many points'
    terms by every row's coefficients reads, made without a second copy)."""
    chunks = chunked(prog, CHUNK_SLOTS, rows)
    if chunks is None:
        return _expand(prog, lo, hi)

    def one(ch: Chunk) -> tuple[np.ndarray, np.ndarray, Pairs, Constraints] | None:
        # (only the chunk's rows are kept: its slots' models are dropped with it)
        ex = _expand(ch.prog, ch.box(lo), ch.box(hi))
        return None if ex is None else (ex.center, ex.half, ex.pairs, chunk_rows(ex.rows, ch))

    done = in_threads(one, chunks)
    if any(d is None for d in done):
        return None
    last = done[-1]
    assert last is not None  # (chunks are never empty)
    parts = [d[3] for d in done if d is not None]
    del done
    coef = _terms_buffer(parts) if by_terms else None
    return Expansion(*last[:3], joined(parts, consume=True, into=coef), coef=coef)


def chunk_rows(rows: Constraints, ch: Chunk) -> Constraints:
    """The rows of a chunk's expansion that the chunk contributes (compile/chunks.py), their
    slots and ids numbered as in the whole program; their keys stay the chunk's (matched
    only against another pass over the same chunk)."""
    part = rows.take(np.flatnonzero(ch.kept(rows.slots)))
    part.slots = ch.slots(part.slots)
    if part.keys is not None:
        part.ids = constraint_ids(ch.prog, part.keys, ch)
    return part


def joined(parts: list[Constraints], consume: bool = False,
           into: np.ndarray | None = None) -> Constraints:
    """The rows of several passes, one after the other, without keys (a key is a place in
    one pass's program); their ids are the whole program's. `consume`: each part's models
    (the caller's own) dropped once copied, the whole and every part never held at once;
    c1 and c2 written into `into` if given (one column a row, _terms_buffer)."""
    ids = None if any(c.ids is None for c in parts) else np.concatenate([c.ids for c in parts])
    lo, hi, slots = (np.concatenate([getattr(c, a) for c in parts])
                     for a in ("lo", "hi", "slots"))
    models = _moved(parts, into) if consume else _concat([c.models for c in parts])
    return Constraints(models, lo, hi, slots, ids=ids)


def constraint_ids(prog: Program, keys: np.ndarray, chunk: Chunk | None = None) -> np.ndarray:
    """The constraint rows of `prog` (a chunk's program if `chunk`) known by their row_key,
    as ids of the whole program: a primitive's output is its primitive's number times the
    outputs a primitive can have, plus the output; a capped temporary's row comes after
    every primitive's, by its slot (ids_end: after every row). A data row's constraints are
    known by its own primitives and slots, so rows joining an expansion leave the others'
    ids as they were."""
    out, total = _outputs(prog), _primitives(prog, chunk)
    group, output, at = keys >> 40, (keys >> 32) & 0xFF, keys & 0xFFFFFFFF
    capped = group >= len(prog.groups)
    prim = np.zeros(len(keys), dtype=np.int64)
    for g in np.unique(group[~capped]):
        mine = group == g
        prim[mine] = prog.groups[int(g)].prim[at[mine]]
    slot = np.where(capped, at, 0)
    if chunk is not None:
        prim, slot = chunk.prims(prim), chunk.slots(slot)
    return np.where(capped, total * out + slot, prim * out + output)


def ids_end(prog: Program) -> int:
    """One past the largest constraint id of the (whole) program `prog` (constraint_ids)."""
    return _primitives(prog, None) * _outputs(prog) + len(prog.slots.lo)


def _outputs(prog: Program) -> int:
    return max((g.out.shape[1] for g in prog.groups), default=1)


def _primitives(prog: Program, chunk: Chunk | None) -> int:
    """The whole program's count of primitives (`prog` a chunk's program if `chunk`)."""
    if chunk is None:
        return len(prog.primitives)
    lay = chunk.layout
    return lay.shared_prims + len(lay.rows) * lay.count


def _expand(prog: Program, lo: np.ndarray, hi: np.ndarray) -> Expansion | None:
    ind = independents(prog)
    if len(ind) == 0 or not supported(prog):
        return None
    plo, phi = lo[ind], hi[ind]
    if not (np.all(np.isfinite(plo)) and np.all(np.isfinite(phi))):
        return None
    n = len(ind)
    pairs = Pairs.of(n)
    p = len(pairs.i)
    plan = _plan(prog, ind)
    if plan.peak_bytes > MAX_TABLE_BYTES:
        return None
    center = 0.5 * plo + 0.5 * phi
    half = up(np.maximum(center - plo, phi - center))
    temp, known = plan.layout.temp, plan.layout.const
    # every slot's constant term and remainder; the coefficients live with the group that
    # defines the slot (`store`), in that group's own unknowns only
    base = constant(np.where(temp, 0.0, lo), np.where(temp, 0.0, hi), 0, 0)
    c0, r = base.c0, base.r
    c0[ind], r[ind] = center, 0.0
    store: list[list[Models]] = []
    found: list[tuple[Models, np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
    for g, mask, cols, gathers in zip(prog.groups, plan.layout.defining, plan.layout.used,
                                      plan.gathers, strict=True):
        local = Pairs.of(len(cols))
        args = [_gathered(c0, r, store, half, col, len(cols), len(local.i), pieces)
                for col, pieces in zip(g.args.T, gathers, strict=True)]
        outs = apply(g.op, args, local)
        store.append(outs)
        for j, out in enumerate(outs):
            slots, d = g.out[:, j], mask[:, j]
            c0[slots[d]], r[slots[d]] = out.c0[d], out.r[d]
            nd = np.flatnonzero(~d)
            if len(nd):
                whole = _widened(out.take(nd), cols, plan.at[len(store) - 1], n, p)
                others = slots[nd][~known[slots[nd]]]
                models = _global(plan, c0, r, store, half, others, n, p)
                found.append((*_constraint(whole, models, slots[nd], known, lo, hi),
                              slots[nd], row_key(len(store) - 1, j, nd)))
        for done in plan.freed[len(store) - 1]:  # no later group reads these models
            store[done] = _FREED
    capped = np.flatnonzero(temp & (np.isfinite(prog.slots.lo) | np.isfinite(prog.slots.hi)))
    if len(capped):
        found.append((_global(plan, c0, r, store, half, capped, n, p), lo[capped], hi[capped],
                      capped, row_key(len(prog.groups), 0, capped)))
    if not found:
        return None
    rows = Constraints(_concat([f[0] for f in found]),
                       *(np.concatenate([f[k] for f in found]) for k in (1, 2, 3, 4)))
    assert rows.keys is not None
    rows.ids = constraint_ids(prog, rows.keys)
    return Expansion(center, half, pairs, rows)


@dataclass
class _Piece:
    """The argument rows `rows` of a group whose models some earlier group's output `out`
    defines (at its rows `src`), and where that group's unknowns `c1_at` and pairs `c2_at`
    sit among this group's; `group` < 0: the rows are unknowns, `src` their columns and
    `c1_at` where those sit."""

    rows: np.ndarray
    group: int
    out: int
    src: np.ndarray
    c1_at: np.ndarray
    c2_at: np.ndarray
    # the source's unknowns and pairs that are among this group's (None: all of them); the
    # others are zero in these rows (a row depends on fewer unknowns than its group)
    c1_of: np.ndarray | None
    c2_of: np.ndarray | None
    whole: bool  # every row, in the same unknowns: a plain take

    def __post_init__(self) -> None:
        # the open-mesh index pairs of the gather's stores, made once (np.ix_ costs as much
        # as a small copy, and a plan is used on every box); its loads take a dimension at
        # a time (_taken), cheaper than a mesh
        self.to1 = np.ix_(self.rows, self.c1_at)
        self.to2 = np.ix_(self.rows, self.c2_at)


@dataclass
class _Plan:
    """What expand does on every box of a program, worked out once: the program's layout
    (each group's unknowns and defining rows), each group's pairs, where each of its
    arguments' models is kept, and when a group's models are read for the last time (they
    are dropped then: a chain reads each level's models once, so the live models are a few
    levels' worth, not one per slot of thousands of configurations)."""

    layout: Layout
    at: list[np.ndarray]  # each group's pairs among all pairs
    gathers: list[list[list[_Piece]]]
    home: tuple[np.ndarray, np.ndarray, np.ndarray]  # (group, output, row) per slot, -1: none
    unknown: np.ndarray  # the column of an unknown's slot, -1 for the others
    freed: list[list[int]]  # after each group: the groups whose models no later one reads
    peak_bytes: float  # the most the live models hold at once


_FREED: list[Models] = []  # a dropped group's models (reading them is a bug: IndexError)


def _plan(prog: Program, ind: np.ndarray) -> _Plan:
    return derived(prog, "taylor plan", lambda: _make_plan(prog, ind))


def _make_plan(prog: Program, ind: np.ndarray) -> _Plan:
    lay = layout(prog, ind)
    n_slots = len(lay.temp)
    unknown = np.full(n_slots, -1, dtype=np.int64)
    unknown[ind] = np.arange(len(ind))
    hg, hj, hr = (np.full(n_slots, -1, dtype=np.int64) for _ in range(3))
    cols, masks = lay.used, lay.defining
    gathers = []
    for k, g in enumerate(prog.groups):
        gathers.append([_pieces(c, cols[k], cols, (hg, hj, hr), unknown) for c in g.args.T])
        for j in range(g.out.shape[1]):
            d = np.flatnonzero(masks[k][:, j])
            hg[g.out[d, j]], hj[g.out[d, j]], hr[g.out[d, j]] = k, j, d
    freed, peak = _lifetimes(prog, lay, gathers, (hg, hj, hr))
    return _Plan(lay, [_pair_index(c, len(ind)) for c in cols], gathers, (hg, hj, hr),
                 unknown, freed, peak)


def _lifetimes(prog: Program, lay: Layout, gathers: list[list[list[_Piece]]],
               home: tuple[np.ndarray, np.ndarray, np.ndarray]) -> tuple[list[list[int]], float]:
    """After which group each group's models are read for the last time (by a later group's
    arguments, or by a constraint row compared with a slot it defines), and the peak of the
    live models' bytes (rows x (1 + unknowns + pairs) x 8 per output)."""
    hg = home[0]
    count = len(prog.groups)
    last = np.arange(count)  # a group reads its own outputs' models as it makes them
    for k, g in enumerate(prog.groups):
        for pieces in gathers[k]:
            for pc in pieces:
                if pc.group >= 0:
                    last[pc.group] = max(int(last[pc.group]), k)
        for j in range(g.out.shape[1]):
            others = g.out[~lay.defining[k][:, j], j]
            src = hg[others[~lay.const[others]]]
            for h in np.unique(src[src >= 0]):
                last[h] = max(int(last[h]), k)
    capped = np.flatnonzero(lay.temp & (np.isfinite(prog.slots.lo) | np.isfinite(prog.slots.hi)))
    for h in np.unique(hg[capped][hg[capped] >= 0]):  # read once more, after the last group
        last[h] = count
    freed: list[list[int]] = [[] for _ in range(count)]
    for h, k in enumerate(last.tolist()):
        if k < count:
            freed[k].append(h)
    size = np.array([g.out.size * (1 + len(c) + len(c) * (len(c) + 1) // 2) * 8.0
                     for g, c in zip(prog.groups, lay.used, strict=True)])
    live = np.zeros(count + 1)
    np.add.at(live, np.arange(count), size)  # born at its own group
    np.add.at(live, np.minimum(last, count - 1) + 1, -size)  # dead after its last reader
    return freed, float(np.cumsum(live).max(initial=0.0))


def _pieces(slots: np.ndarray, dest: np.ndarray, cols: list[np.ndarray],
            home: tuple[np.ndarray, np.ndarray, np.ndarray], unknown: np.ndarray,
            done: int | None = None) -> list[_Piece]:
    """How to gather the models of `slots` in the unknowns `dest` (sorted column numbers),
    from the groups before `done` (all if None)."""
    hg, hj, hr = home
    pieces = []
    u = np.flatnonzero(unknown[slots] >= 0)
    if len(u):
        at = np.searchsorted(dest, unknown[slots[u]])
        pieces.append(_Piece(u, -1, -1, unknown[slots[u]], at, np.zeros(0, np.int64), None,
                             None, False))
    g = hg[slots]
    key = np.where((g >= 0) & (g < (len(cols) if done is None else done)),
                   2 * g + hj[slots], -1)
    for k in np.unique(key[key >= 0]):
        rows = np.flatnonzero(key == k)
        src_cols = cols[k // 2]
        c1_of = np.flatnonzero(np.isin(src_cols, dest))
        c1_at = np.searchsorted(dest, src_cols[c1_of])
        c2_at = _pair_index(c1_at, len(dest))
        full = len(c1_of) == len(src_cols)
        # the source's pairs among both members in dest, in the order of _pair_index
        c2_of = None if full else _pair_index(c1_of, len(src_cols))
        whole = len(rows) == len(slots) and full and len(src_cols) == len(dest)
        pieces.append(_Piece(rows, int(k // 2), int(k % 2), hr[slots[rows]], c1_at, c2_at,
                             None if full else c1_of, c2_of, whole))
    return pieces


def _pair_index(cols: np.ndarray, n: int) -> np.ndarray:
    """The positions in Pairs.of(n) of the pairs of Pairs.of(len(cols)), mapped by cols."""
    i, j = np.triu_indices(len(cols))
    gi, gj = cols[i], cols[j]
    return gi * n - gi * (gi - 1) // 2 + (gj - gi)


def _gathered(c0: np.ndarray, r: np.ndarray, store: list[list[Models]], half: np.ndarray,
              slots: np.ndarray, n: int, p: int, pieces: list[_Piece]) -> Models:
    """The models of `slots` in a group's n unknowns and p pairs (zero where a slot has no
    coefficient: a constant, or a temporary no group defines before)."""
    if len(pieces) == 1 and pieces[0].whole:
        s = store[pieces[0].group][pieces[0].out]
        return Models(c0[slots], np.take(s.c1, pieces[0].src, axis=0),
                      np.take(s.c2, pieces[0].src, axis=0), r[slots])
    c1, c2 = np.zeros((len(slots), n)), np.zeros((len(slots), p))
    for pc in pieces:
        if pc.group < 0:
            c1[pc.rows, pc.c1_at] = half[pc.src]
            continue
        s = store[pc.group][pc.out]
        c1[pc.to1] = _taken(s.c1, pc.src, pc.c1_of)
        c2[pc.to2] = _taken(s.c2, pc.src, pc.c2_of)
    return Models(c0[slots], c1, c2, r[slots])


def _taken(a: np.ndarray, rows: np.ndarray, cols: np.ndarray | None) -> np.ndarray:
    """a[rows][:, cols] (every column if cols is None), a dimension at a time."""
    out = np.take(a, rows, axis=0)
    return out if cols is None else np.take(out, cols, axis=1)


def _global(plan: _Plan, c0: np.ndarray, r: np.ndarray, store: list[list[Models]],
            half: np.ndarray, slots: np.ndarray, n: int, p: int) -> Models:
    """The models of `slots` in all the unknowns, as the groups done so far define them."""
    pieces = _pieces(slots, np.arange(n), plan.layout.used, plan.home, plan.unknown,
                     len(store))
    return _gathered(c0, r, store, half, slots, n, p, pieces)


def _widened(m: Models, cols: np.ndarray, at: np.ndarray, n: int, p: int) -> Models:
    c1, c2 = np.zeros((len(m.c0), n)), np.zeros((len(m.c0), p))
    c1[:, cols], c2[:, at] = m.c1, m.c2
    return Models(m.c0, c1, c2, m.r)


def _put(table: Models, slots: np.ndarray, m: Models) -> None:
    table.c0[slots], table.c1[slots], table.c2[slots], table.r[slots] = m.c0, m.c1, m.c2, m.r


def _constraint(f: Models, models: Models, slots: np.ndarray, known: np.ndarray,
                lo: np.ndarray, hi: np.ndarray) -> tuple[Models, np.ndarray, np.ndarray]:
    """f = s: a constant s (a measured value) is f's target range; an unknown or a temporary
    computed elsewhere (`models`: theirs, in order) gives the row f - s in [0, 0]."""
    other = ~known[slots]
    tlo, thi = lo[slots].copy(), hi[slots].copy()
    if np.any(other):
        k = np.flatnonzero(other)
        diff = add(f.take(k), models, -1.0)
        f = Models(f.c0.copy(), f.c1.copy(), f.c2.copy(), f.r.copy())
        _put(f, k, diff)
        tlo[k], thi[k] = 0.0, 0.0
    return f, tlo, thi


def _concat(ms: list[Models]) -> Models:
    return Models(*(np.concatenate([getattr(m, a) for m in ms]) for a in ("c0", "c1", "c2", "r")))


def _terms_buffer(parts: list[Constraints]) -> np.ndarray:
    """An empty (terms, rows) array for the parts' joined c1 and c2, one column a row."""
    first = parts[0].models
    k = sum(len(c.models.c0) for c in parts)
    return np.empty((first.c1.shape[1] + first.c2.shape[1], k))


def _moved(parts: list[Constraints], into: np.ndarray | None = None) -> Models:
    """_concat of the parts' models, each part's models replaced by none (no rows) once
    copied into the whole (c1 and c2 views of `into`, one column a row, if given)."""
    first = parts[0].models
    k, n = sum(len(c.models.c0) for c in parts), first.c1.shape[1]
    if into is None:
        out = Models(np.empty(k), np.empty((k, n)), np.empty((k,) + first.c2.shape[1:]),
                     np.empty(k))
    else:
        out = Models(np.empty(k), into[:n].T, into[n:].T, np.empty(k))
    a = 0
    for c in parts:
        m, b = c.models, a + len(c.models.c0)
        out.c0[a:b], out.c1[a:b], out.c2[a:b], out.r[a:b] = m.c0, m.c1, m.c2, m.r
        c.models, a = m.take(np.zeros(0, dtype=np.int64)), b
        del m
    return out
