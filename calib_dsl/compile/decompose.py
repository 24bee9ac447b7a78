"""Decomposition: the elaborated DAG becomes three-address primitive constraints.

Each DAG node that is an operation becomes one primitive `out = op(args)`. A constraint
`lhs == rhs` does not become a primitive: its two sides are the same unknown, so their nodes
are merged into one *slot* (union-find). That is how the root of `y1 == a2 + a4` is bound to
the declared variable: the listing reads `y1 = t2 + t3`. `lhs <= rhs` caps the slot of
`lhs - rhs` to ]-oo, 0]. Merging can make two primitives identical (same op on the same slots);
they are merged too, until nothing changes (congruence closure), so CSE survives unification.
"""

from __future__ import annotations

import numpy as np

from calib_dsl.arith.interval import INF
from calib_dsl.compile.merge import (
    DagArrays,
    UnionFind,
    congruence_closure,
    first_of_each,
    live_nodes,
    node_locations,
)
from calib_dsl.frontend.diagnostics import Loc
from calib_dsl.ir.dag import TERNARY, Dag
from calib_dsl.ir.model import Model
from calib_dsl.ir.primitives import Primitive, PrimitiveArrays, Slots, format_const
from calib_dsl.ir.status import SlotKind


def decompose(model: Model) -> tuple[Slots, list[Primitive]]:
    slots, prims, _ = decompose_arrays(model)
    return slots, prims


def decompose_arrays(model: Model) -> tuple[Slots, list[Primitive], PrimitiveArrays]:
    """decompose, and the primitives as arrays too. The passes over the DAG are numpy passes
    over its nodes (one per level where a node needs its arguments done)."""
    dag = model.dag
    caps, cap_owner, cap_cells = _relations_to_caps(dag)  # may add `sub` nodes (inequalities)
    _complete_rotations(dag)
    g = DagArrays(dag)
    live = live_nodes(dag, g, [c.lhs for c in dag.constraints]
                       + [c.rhs for c in dag.constraints]
                       + [c[0] for c in caps] + [v.node for v in dag.variables.values()])
    first_root, root_locs = node_locations(dag, g, caps, cap_owner)
    uf = UnionFind(g.n)
    for c in dag.constraints:
        if c.rel == "==" and not (_interval_const(dag, c.lhs) or _interval_const(dag, c.rhs)):
            uf.union(c.lhs, c.rhs)
    rep = np.arange(g.n, dtype=np.int64)
    for c in dag.constraints:
        for side in (c.lhs, c.rhs):
            rep[side] = uf.find(side)
    rep = congruence_closure(g, live, rep)
    slot_of, slots = _make_slots(dag, g, live, rep, caps)
    slots.measured_sides = _measured_sides(dag, caps, cap_cells, slot_of, slots)
    slots.implied = _implied(dag, g, (caps, cap_owner, cap_cells), slot_of)
    temp = np.array([k == SlotKind.TEMP for k in slots.kinds], dtype=bool)
    prims, arrays = _make_primitives(dag, g, live, slot_of, first_root, root_locs, temp)
    _name_temporaries(slots, arrays)
    return slots, prims, arrays


def _interval_const(dag: Dag, node: int) -> bool:
    """A constant that is an interval, not a point: `x == [0.9, 1.1]` says x lies in it, not
    that x IS that constant (two unknowns stated equal to it are not equal to each other)."""
    n = dag.nodes[node]
    return n.op == "const" and n.data[0] != n.data[1]


def _relations_to_caps(dag: Dag) -> tuple[list[tuple[int, float, float, Loc | None]],
                                            list[int], list[int]]:
    """Domain caps (node, lo, hi, loc): inequalities on `lhs - rhs`, and equalities with an
    interval constant (membership, not identity: no merging of slots through it); the index
    of the constraint each cap comes from; and the constant's node (-1 for an inequality)."""
    caps, owner, cells = [], [], []
    for ci, c in enumerate(dag.constraints):
        if c.rel == "==":
            for side, other in ((c.lhs, c.rhs), (c.rhs, c.lhs)):
                if _interval_const(dag, other):
                    lo, hi = dag.nodes[other].data[:2]
                    caps.append((side, lo, hi, c.loc))
                    owner.append(ci)
                    cells.append(other)
                    break
        elif c.rel in ("<=", ">="):
            cap = (-INF, 0.0) if c.rel == "<=" else (0.0, INF)
            caps.append((dag.op("sub", c.lhs, c.rhs), *cap, c.loc))
            owner.append(ci)
            cells.append(-1)
    return caps, owner, cells


def _implied(dag: Dag, g: DagArrays, capped: tuple[list, list[int], list[int]],
             slot_of: np.ndarray) -> set[int]:
    """The slots that only implied equalities merge or cap (no other constraint compares
    them; an implied entry the model computes as a constant caps the other side). Their
    proof gives the measured values they read (an orientation's angles) the values the
    measured rows computed, so none if such a value enters any other constraint."""
    if not any(c.implied for c in dag.constraints):
        return set()
    caps, owners, cells = capped
    implied: set[int] = set()
    other: set[int] = set()
    own: list[int] = []
    rest: list[int] = []
    for cap, ci in zip(caps, owners, strict=True):
        slot = int(slot_of[cap[0]])
        (implied if dag.constraints[ci].implied else other).add(slot)
        (own if dag.constraints[ci].implied else rest).append(int(cap[0]))
    for c in dag.constraints:
        slot = int(slot_of[c.lhs])
        if c.rel == "==" and slot >= 0 and slot == int(slot_of[c.rhs]):
            (implied if c.implied else other).add(slot)
            (own if c.implied else rest).extend((c.lhs, c.rhs))
    # the measured values (a constant the model computed is read anywhere: nothing moves it)
    moved = np.array(sorted({c for c in cells if c >= 0 and dag.cells.get(c)}),
                     dtype=np.int64)
    shared = live_nodes(dag, g, own)[moved] & live_nodes(dag, g, rest)[moved]
    return set() if shared.any() else implied - other


def _measured_sides(dag: Dag, caps: list, cells: list[int], slot_of: np.ndarray,
                    slots: Slots) -> dict[int, tuple[int, int]]:
    """The slots a constraint compares with a measured value (`f == m.x[k]`: f's slot, its
    domain capped to the cell's interval), and that cell's (cell_row, cell_col) ids."""
    row_keys, col_keys = slots.row_keys or [], slots.col_keys or []
    rows = {k: i for i, k in enumerate(row_keys)}
    cols = {k: i for i, k in enumerate(col_keys)}
    out: dict[int, tuple[int, int]] = {}
    for (node, *_), cell in zip(caps, cells, strict=True):
        tags = dag.cells.get(cell) if cell >= 0 else None
        if tags and slot_of[node] >= 0:
            table, column, row = min(tags)
            # the cell itself is no slot (its interval caps f's): new ids where none is
            r = rows.setdefault((table, row), len(rows))
            c = cols.setdefault((table, column), len(cols))
            old = out.get(int(slot_of[node]))
            if old is not None and old[0] != r:
                slots.capped_by_rows.add(int(slot_of[node]))
            out[int(slot_of[node])] = (r, c)
    slots.row_keys, slots.col_keys = list(rows), list(cols)
    return out





def _complete_rotations(dag: Dag) -> None:
    """A rotation is one primitive with two outputs: make sure both output nodes exist."""
    for node in [node for node in dag.nodes if node.op in TERNARY]:
        dag.op("rotv" if node.op == "rotu" else "rotu", *node.args)


def _make_slots(dag: Dag, g: DagArrays, live: np.ndarray, rep: np.ndarray, caps: list):
    declared = [v for v in dag.variables.values()]
    first: dict[int, int] = {}
    for v in declared:  # declared unknowns first, in declaration order
        first.setdefault(int(rep[v.node]), len(first))
    live_idx = np.flatnonzero(live)
    reps = rep[live_idx]
    _, at = np.unique(reps, return_index=True)
    in_order = reps[np.sort(at)]  # the classes in the order of their first live node
    known = np.array(list(first), dtype=np.int64)
    in_order = in_order[~np.isin(in_order, known)]
    slot_of_rep = np.full(len(rep), -1, dtype=np.int64)
    slot_of_rep[known] = np.arange(len(known))
    slot_of_rep[in_order] = len(known) + np.arange(len(in_order))
    m = len(known) + len(in_order)
    lo, hi = np.full(m, -INF), np.full(m, INF)
    names = [""] * m
    kinds: list[str] = [SlotKind.TEMP] * m
    origin: list[Loc | None] = [None] * m
    slot_of = np.full(g.n, -1, dtype=np.int64)
    slot_of[live_idx] = slot_of_rep[reps]
    # a constant stated equal to something: an empty slot is that constraint's fault
    const_loc = {side: c.loc for c in dag.constraints for side in (c.lhs, c.rhs)
                 if dag.nodes[side].op == "const"}
    const = g.codes.get("const")
    consts = live_idx[g.op[live_idx] == const] if const is not None else live_idx[:0]
    for v in reversed(declared):  # first declared name wins the slot's name
        s = slot_of[v.node]
        _narrow(lo, hi, origin, s, v.lo, v.hi, v.loc)
        names[s], kinds[s] = v.name, SlotKind(v.kind)
    for i in consts.tolist():  # constants: the slot is that value
        node = dag.nodes[i]
        s = int(slot_of[i])
        _narrow(lo, hi, origin, s, node.data[0], node.data[1], const_loc.get(i))
        if kinds[s] == SlotKind.TEMP:
            kinds[s], names[s] = SlotKind.CONST, format_const(node.data[0], node.data[1])
    for node, clo, chi, loc in caps:
        _narrow(lo, hi, origin, slot_of[node], clo, chi, loc)
    decl_slots = [int(slot_of[v.node]) for v in declared]
    rows, cols, keys, col_keys = _cell_tags(dag, slot_of, m)
    return slot_of, Slots(names, kinds, lo, hi, origin, decl_slots, [v.name for v in declared],
                          rows, cols, keys, col_keys)


def _cell_tags(dag: Dag, slot_of: np.ndarray, m: int
               ) -> tuple[np.ndarray, np.ndarray, list[tuple[str, int]], list[tuple[str, str]]]:
    row_ids: dict[tuple[str, int], int] = {}
    col_ids: dict[tuple[str, str], int] = {}
    rows, cols = np.full(m, -1, dtype=np.int64), np.full(m, -1, dtype=np.int64)
    for node, tags in dag.cells.items():
        s = slot_of[node]
        if s < 0:
            continue
        for table, column, row in tags:
            r = row_ids.setdefault((table, row), len(row_ids))
            c = col_ids.setdefault((table, column), len(col_ids))
            if rows[s] == -1:
                rows[s], cols[s] = r, c
            elif rows[s] != r or cols[s] != c:
                rows[s] = -2
    return rows, cols, list(row_ids), list(col_ids)


def _narrow(lo, hi, origin, s, a: float, b: float, loc: Loc | None) -> None:
    if a > lo[s] or b < hi[s]:
        origin[s] = loc if loc is not None else origin[s]
    lo[s], hi[s] = max(lo[s], a), min(hi[s], b)


def _make_primitives(dag: Dag, g: DagArrays, live: np.ndarray, slot_of: np.ndarray,
                     first_root: np.ndarray, root_locs: list[Loc | None], temp: np.ndarray
                     ) -> tuple[list[Primitive], PrimitiveArrays]:
    """One primitive per live operation node, in node order; a rotation's two output nodes
    make one `rot`. Primitives identical after merging (same op, output and argument slots,
    data) are kept once, the first."""
    idx = np.flatnonzero(live & (g.arity > 0))
    rot = g.sibling[idx] >= 0
    arity = g.arity[idx]
    args = np.where(g.args[idx] >= 0, slot_of[np.maximum(g.args[idx], 0)], -1)
    out = np.full((len(idx), 2), -1, dtype=np.int64)
    out[:, 0] = slot_of[idx]
    if rot.any():
        rotu = g.codes.get("rotu", -1)
        is_u = g.op[idx] == rotu
        u = np.where(is_u, idx, g.sibling[idx])
        v = np.where(is_u, g.sibling[idx], idx)
        out[rot, 0] = slot_of[u[rot]]
        out[rot, 1] = slot_of[v[rot]]
    op = np.where(rot, -1, g.op[idx])  # rotu and rotv are both `rot`
    # a + b and b + a are the same primitive once merging has made them meet
    commutative = np.isin(op, [g.codes[o] for o in ("add", "mul") if o in g.codes])
    key_args = args.copy()
    key_args[commutative, :2] = np.sort(args[commutative, :2], axis=1)
    keep = first_of_each(np.column_stack([op, g.data[idx], out, key_args]))
    if keep is not None:
        idx, rot, arity, args, out = idx[keep], rot[keep], arity[keep], args[keep], out[keep]
    level = _consistent_levels(g.level[idx], out, args, temp)
    names = g.names
    ilist = idx.tolist()
    ops = ["rot" if r else names[i] for i, r in zip(ilist, rot.tolist(), strict=True)]
    nodes = dag.nodes
    params = [None if nodes[i].data is None else float(nodes[i].data) for i in ilist]
    locs = [root_locs[r] for r in first_root[idx].tolist()]
    out0 = out[:, 0].tolist()
    out_l: list[tuple[int, ...]] = [(a,) for a in out0]
    for k in np.flatnonzero(rot).tolist():
        out_l[k] = (out0[k], int(out[k, 1]))
    cols = [args[:, j].tolist() for j in range(3)]
    args_l: list[tuple[int, ...]] = list(zip(cols[0], cols[1], cols[2], strict=True))
    for k in np.flatnonzero(arity != 3).tolist():
        args_l[k] = args_l[k][:int(arity[k])]
    prims = list(map(_new_primitive, zip(ops, out_l, args_l, params, locs, level.tolist(),
                                         strict=True)))
    return prims, PrimitiveArrays(ops, out, args, arity, params, level)


def _consistent_levels(level: np.ndarray, out: np.ndarray, args: np.ndarray,
                       temp: np.ndarray) -> np.ndarray:
    """Levels such that every temporary a primitive reads is produced at a lower level. The
    DAG's levels are, but merging slots can break them: sin(q) and sin(cos(cos(a))) are one
    primitive once q == cos(cos(a)), kept at the level of one of the two, and a sweep would
    read the temporary before the step that narrows it. Raised to the least fixed point of
    level >= 1 + (lowest level producing each temporary argument); other slots (declared
    unknowns, data, constants) are inputs at level 0. A cycle of temporaries keeps its levels."""
    level = level.copy()
    if len(level) == 0:
        return level
    m = len(temp)
    big = np.iinfo(np.int64).max
    outs = out.ravel()
    who = np.repeat(np.arange(len(level)), out.shape[1])
    who, outs = who[outs >= 0], outs[outs >= 0]
    safe = np.where(args >= 0, args, m)  # slot m: the padding, an input
    reads_temp = np.append(temp, False)[safe]
    for _ in range(len(level)):
        lowest = np.full(m + 1, big, dtype=np.int64)
        np.minimum.at(lowest, outs, level[who])
        at = np.where(reads_temp, lowest[safe], 0)
        at = np.where(at == big, 0, at)
        need = 1 + at.max(axis=1)
        low = level < need
        if not low.any() or np.any(need[low] > len(level)):  # consistent, or a cycle
            return level
        level[low] = need[low]
    return level


def _new_primitive(fields: tuple) -> Primitive:
    """Primitive(*fields), without the named tuple's Python-level constructor."""
    return tuple.__new__(Primitive, fields)


def _name_temporaries(slots: Slots, arrays: PrimitiveArrays) -> None:
    """t1, t2, ... for the temporaries, in the order the primitives first output them."""
    outs = arrays.out.ravel()
    outs = outs[outs >= 0]
    temp = np.array([k == SlotKind.TEMP and not n for k, n in zip(slots.kinds, slots.names,
                                                           strict=True)], dtype=bool)
    outs = outs[temp[outs]]
    _, at = np.unique(outs, return_index=True)
    count = 0
    for s in outs[np.sort(at)].tolist():
        count += 1
        slots.names[s] = f"t{count}"
    for s, name in enumerate(slots.names):  # unused temporaries cannot exist, but be safe
        if not name:
            count += 1
            slots.names[s] = f"t{count}"
