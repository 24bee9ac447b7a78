"""Decomposition: the elaborated DAG becomes three-address primitive constraints.

Each DAG node that is an operation becomes one primitive `out = op(args)`. A constraint
`lhs == rhs` does not become a primitive: its two sides are the same unknown, so their nodes
are merged into one *slot* (union-find). That is how the root of `y1 == a2 + a4` is bound to
the declared variable: the listing reads `y1 = t2 + t3`. `lhs <= rhs` caps the slot of
`lhs - rhs` to ]-oo, 0]. Merging can make two primitives identical (same op on the same slots);
they are merged too, until nothing changes (congruence closure), so CSE survives unification.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from calib_dsl.frontend.diagnostics import Loc
from calib_dsl.ir.dag import Dag, Node
from calib_dsl.ir.model import Model

INF = float("inf")


class Primitive(NamedTuple):
    """out = op(args); a named tuple (the compiler makes hundreds of thousands)."""

    op: str  # a DAG op; "rot" joins rotu/rotv: out = (u2, v2), args = (beta, u, v)
    out: tuple[int, ...]
    args: tuple[int, ...]
    param: float | None
    loc: Loc | None
    level: int


@dataclass
class Slots:
    """The unknowns and constants of the program, one per class of merged DAG nodes."""

    names: list[str]
    kinds: list[str]  # "param" | "var" | "data" | "const" | "temp"
    lo: np.ndarray
    hi: np.ndarray
    # Where each slot's initial domain was last narrowed (declaration or constraint).
    origin: list[Loc | None]
    declared: list[int]  # slots of declared unknowns, in declaration order
    declared_names: list[str]
    # Measured cells: the configuration (table row) and table column a constant slot was read
    # from; -1 for other slots, -2 for a constant shared by several configurations.
    cell_row: np.ndarray | None = None
    cell_col: np.ndarray | None = None


class _UnionFind:
    def __init__(self, n: int) -> None:
        self.parent = list(range(n))

    def find(self, i: int) -> int:
        root = i
        while self.parent[root] != root:
            root = self.parent[root]
        while self.parent[i] != root:  # path compression
            self.parent[i], i = root, self.parent[i]
        return root

    def union(self, a: int, b: int) -> bool:
        ra, rb = self.find(a), self.find(b)
        if ra == rb:
            return False
        self.parent[max(ra, rb)] = min(ra, rb)
        return True


def decompose(model: Model) -> tuple[Slots, list[Primitive]]:
    slots, prims, _ = decompose_arrays(model)
    return slots, prims


@dataclass
class PrimitiveArrays:
    """The primitives as arrays, in the order of the list (program.py groups them from these).
    `out` has two columns (-1 in the second but for rot), `args` three (-1 past the arity)."""

    op: list[str]
    out: np.ndarray
    args: np.ndarray
    arity: np.ndarray
    param: list[float | None]
    level: np.ndarray


def decompose_arrays(model: Model) -> tuple[Slots, list[Primitive], PrimitiveArrays]:
    """decompose, and the primitives as arrays too. The passes over the DAG are numpy passes
    over its nodes (one per level where a node needs its arguments done)."""
    dag = model.dag
    caps, cap_owner = _relations_to_caps(dag)  # may add `sub` nodes for inequalities
    _complete_rotations(dag)
    g = _DagArrays(dag)
    live = _live_nodes(dag, g, [c.lhs for c in dag.constraints]
                       + [c.rhs for c in dag.constraints]
                       + [c[0] for c in caps] + [v.node for v in dag.variables.values()])
    first_root, root_locs = _node_locations(dag, g, caps, cap_owner)
    uf = _UnionFind(g.n)
    for c in dag.constraints:
        if c.rel == "==" and not (_interval_const(dag, c.lhs) or _interval_const(dag, c.rhs)):
            uf.union(c.lhs, c.rhs)
    rep = np.arange(g.n, dtype=np.int64)
    for c in dag.constraints:
        for side in (c.lhs, c.rhs):
            rep[side] = uf.find(side)
    rep = _congruence_closure(g, live, rep)
    slot_of, slots = _make_slots(dag, g, live, rep, caps)
    temp = np.array([k == "temp" for k in slots.kinds], dtype=bool)
    prims, arrays = _make_primitives(dag, g, live, slot_of, first_root, root_locs, temp)
    _name_temporaries(slots, arrays)
    return slots, prims, arrays


def _interval_const(dag: Dag, node: int) -> bool:
    """A constant that is an interval, not a point: `x == [0.9, 1.1]` says x lies in it, not
    that x IS that constant (two unknowns stated equal to it are not equal to each other)."""
    n = dag.nodes[node]
    return n.op == "const" and n.data[0] != n.data[1]


def _relations_to_caps(dag: Dag) -> tuple[list[tuple[int, float, float, Loc | None]],
                                            list[int]]:
    """Domain caps (node, lo, hi, loc): inequalities on `lhs - rhs`, and equalities with an
    interval constant (membership, not identity: no merging of slots through it); and the
    index of the constraint each cap comes from."""
    caps, owner = [], []
    for ci, c in enumerate(dag.constraints):
        if c.rel == "==":
            for side, other in ((c.lhs, c.rhs), (c.rhs, c.lhs)):
                if _interval_const(dag, other):
                    lo, hi = dag.nodes[other].data[:2]
                    caps.append((side, lo, hi, c.loc))
                    owner.append(ci)
                    break
        elif c.rel in ("<=", ">="):
            cap = (-INF, 0.0) if c.rel == "<=" else (0.0, INF)
            caps.append((dag.op("sub", c.lhs, c.rhs), *cap, c.loc))
            owner.append(ci)
    return caps, owner


_ROT = ("rotu", "rotv")


def _complete_rotations(dag: Dag) -> None:
    """A rotation is one primitive with two outputs: make sure both output nodes exist."""
    for node in [node for node in dag.nodes if node.op in _ROT]:
        dag.op("rotv" if node.op == "rotu" else "rotu", *node.args)


class _DagArrays:
    """The DAG's nodes as arrays: op codes, arguments (n, 3) padded with -1, arity, level,
    a code for the node's data (0: None), and the other output of a rotation (-1: none);
    plus the node ids sorted by level."""

    def __init__(self, dag: Dag) -> None:
        nodes = dag.nodes
        n = self.n = len(nodes)
        self.names = [node.op for node in nodes]
        codes = self.codes = {o: k for k, o in enumerate(dict.fromkeys(self.names))}
        self.op = np.fromiter(map(codes.__getitem__, self.names), dtype=np.int64, count=n)
        args = [node.args for node in nodes]
        self.arity = np.fromiter(map(len, args), dtype=np.int64, count=n)
        flat = np.fromiter(itertools.chain.from_iterable(args), dtype=np.int64,
                           count=int(self.arity.sum()))
        self.args = np.full((n, 3), -1, dtype=np.int64)
        rows = np.repeat(np.arange(n), self.arity)
        starts = np.cumsum(self.arity) - self.arity
        self.args[rows, np.arange(len(flat)) - starts[rows]] = flat
        datas: dict[Any, int] = {}
        self.data = np.zeros(n, dtype=np.int64)
        for i in np.flatnonzero(self.arity > 0).tolist():  # operations: an exponent, or None
            data = nodes[i].data
            if data is not None:
                self.data[i] = datas.setdefault(data, len(datas) + 1)
        levels = getattr(dag, "_levels", None)
        if levels is not None and len(levels) == n:
            self.level = np.array(levels, dtype=np.int64)
        else:  # a DAG whose levels were not kept: one pass (ids are topological)
            lv = [0] * n
            for i, a in enumerate(args):
                if a:
                    lv[i] = 1 + max(lv[j] for j in a)
            self.level = np.array(lv, dtype=np.int64)
        self.sibling = np.full(n, -1, dtype=np.int64)
        rot = [codes[o] for o in _ROT if o in codes]
        for i in np.flatnonzero(np.isin(self.op, rot)).tolist():
            other = "rotv" if self.names[i] == "rotu" else "rotu"
            self.sibling[i] = dag._table[Node(other, nodes[i].args)]
        self.by_level = np.argsort(self.level, kind="stable")
        self.level_start = np.searchsorted(self.level[self.by_level],
                                           np.arange(int(self.level.max(initial=0)) + 2))

    def at_level(self, level: int) -> np.ndarray:
        return self.by_level[self.level_start[level]:self.level_start[level + 1]]

    def top(self) -> int:
        return len(self.level_start) - 2


def _live_nodes(dag: Dag, g: _DagArrays, roots: list[int]) -> np.ndarray:
    """The nodes the roots reach (a rotation's two outputs live together), level by level
    from the top: a node's arguments are on lower levels."""
    live = np.zeros(g.n, dtype=bool)
    live[roots] = True
    for level in range(g.top(), 0, -1):
        idx = g.at_level(level)
        on = idx[live[idx]]
        sib = g.sibling[on]
        live[sib[sib >= 0]] = True  # same arguments, so the same level
        on = idx[live[idx]]
        a = g.args[on].ravel()
        live[a[a >= 0]] = True
    return live


def _node_locations(dag: Dag, g: _DagArrays, caps: list, cap_owner: list[int]
                    ) -> tuple[np.ndarray, list[Loc | None]]:
    """Each node takes the location of the first constraint in source order that reaches it
    (either side, or its cap): per node, the index of that constraint (len: none), and the
    constraints' locations."""
    cons = dag.constraints
    nodes = [c.lhs for c in cons] + [c.rhs for c in cons] + [c[0] for c in caps]
    rank = list(range(len(cons))) * 2 + list(cap_owner)
    none = len(cons)
    first = np.full(g.n, none, dtype=np.int64)
    if nodes:
        np.minimum.at(first, np.array(nodes, dtype=np.int64), np.array(rank, dtype=np.int64))
    for level in range(g.top(), 0, -1):
        idx = g.at_level(level)
        idx = idx[first[idx] < none]
        for j in range(3):
            a = g.args[idx, j]
            has = a >= 0
            np.minimum.at(first, a[has], first[idx[has]])
    return first, [c.loc for c in cons] + [None]


def _congruence_closure(g: _DagArrays, live: np.ndarray, rep: np.ndarray) -> np.ndarray:
    """Merge the outputs of primitives that became identical after merging their inputs:
    `rep` maps each node to the smallest node of its class; repeated to the fixed point."""
    ops = np.flatnonzero(live & (g.arity > 0))
    if len(ops) == 0:
        return rep
    op, data, args = g.op[ops], g.data[ops], g.args[ops]
    commutative = np.isin(op, [g.codes[o] for o in ("add", "mul") if o in g.codes])
    while True:
        r = np.where(args >= 0, rep[np.maximum(args, 0)], -1)
        a0 = np.where(commutative, np.minimum(r[:, 0], r[:, 1]), r[:, 0])
        a1 = np.where(commutative, np.maximum(r[:, 0], r[:, 1]), r[:, 1])
        order = np.lexsort((r[:, 2], a1, a0, data, op))
        keys = np.stack([op, data, a0, a1, r[:, 2]])[:, order]
        new = np.ones(len(order), dtype=bool)
        new[1:] = (keys[:, 1:] != keys[:, :-1]).any(axis=0)
        head = np.maximum.accumulate(np.where(new, np.arange(len(order)), 0))
        u, v = rep[ops[order]], rep[ops[order[head]]]
        pairs = u != v
        if not pairs.any():
            return rep
        u, v = u[pairs], v[pairs]
        label = np.arange(len(rep), dtype=np.int64)
        while True:  # connected components of the classes joined by the pairs: min label
            m = np.minimum(label[u], label[v])
            np.minimum.at(label, u, m)
            np.minimum.at(label, v, m)
            while True:
                jumped = label[label]
                if np.array_equal(jumped, label):
                    break
                label = jumped
            if np.array_equal(label[u], label[v]):
                break
        rep = label[rep]


def _make_slots(dag: Dag, g: _DagArrays, live: np.ndarray, rep: np.ndarray, caps: list):
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
    kinds = ["temp"] * m
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
        names[s], kinds[s] = v.name, v.kind
    for i in consts.tolist():  # constants: the slot is that value
        node = dag.nodes[i]
        s = int(slot_of[i])
        _narrow(lo, hi, origin, s, node.data[0], node.data[1], const_loc.get(i))
        if kinds[s] == "temp":
            kinds[s], names[s] = "const", format_const(node.data[0], node.data[1])
    for node, clo, chi, loc in caps:
        _narrow(lo, hi, origin, slot_of[node], clo, chi, loc)
    decl_slots = [int(slot_of[v.node]) for v in declared]
    rows, cols = _cell_tags(dag, slot_of, m)
    return slot_of, Slots(names, kinds, lo, hi, origin, decl_slots, [v.name for v in declared],
                          rows, cols)


def _cell_tags(dag: Dag, slot_of: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
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
    return rows, cols


def _narrow(lo, hi, origin, s, a: float, b: float, loc: Loc | None) -> None:
    if a > lo[s] or b < hi[s]:
        origin[s] = loc if loc is not None else origin[s]
    lo[s], hi[s] = max(lo[s], a), min(hi[s], b)


def _make_primitives(dag: Dag, g: _DagArrays, live: np.ndarray, slot_of: np.ndarray,
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
    keep = _first_of_each(np.column_stack([op, g.data[idx], out, key_args]))
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


def _first_of_each(keys: np.ndarray) -> np.ndarray | None:
    """The sorted indices of the first row of each distinct row of keys (None: all distinct).
    Rows with different outputs (column 2) differ, so only rows sharing one are compared."""
    _, inverse, counts = np.unique(keys[:, 2], return_inverse=True, return_counts=True)
    shared = np.flatnonzero(counts[inverse] > 1)
    if len(shared) == 0:
        return None
    seen: set[tuple[int, ...]] = set()
    drop = []
    for k, row in zip(shared.tolist(), map(tuple, keys[shared].tolist()), strict=True):
        if row in seen:
            drop.append(k)
        else:
            seen.add(row)
    if not drop:
        return None
    keep = np.ones(len(keys), dtype=bool)
    keep[drop] = False
    return np.flatnonzero(keep)


def _name_temporaries(slots: Slots, arrays: PrimitiveArrays) -> None:
    """t1, t2, ... for the temporaries, in the order the primitives first output them."""
    outs = arrays.out.ravel()
    outs = outs[outs >= 0]
    temp = np.array([k == "temp" and not n for k, n in zip(slots.kinds, slots.names,
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


def format_const(lo: float, hi: float) -> str:
    """A constant as the user wrote it: a decimal's enclosure prints as that decimal."""
    if lo == hi:
        return _short(lo)
    if np.nextafter(lo, INF) == hi:
        return min(_short(lo), _short(hi), key=len)
    return f"[{_short(lo)}, {_short(hi)}]"


def _short(x: float) -> str:
    if x == INF:
        return "+oo"
    if x == -INF:
        return "-oo"
    text = repr(float(x))
    return text[:-2] if text.endswith(".0") else text
