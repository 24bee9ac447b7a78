"""Decomposition: the elaborated DAG becomes three-address primitive constraints.

Each DAG node that is an operation becomes one primitive `out = op(args)`. A constraint
`lhs == rhs` does not become a primitive: its two sides are the same unknown, so their nodes
are merged into one *slot* (union-find). That is how the root of `y1 == a2 + a4` is bound to
the declared variable: the listing reads `y1 = t2 + t3`. `lhs <= rhs` caps the slot of
`lhs - rhs` to ]-oo, 0]. Merging can make two primitives identical (same op on the same slots);
they are merged too, until nothing changes (congruence closure), so CSE survives unification.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .dag import Dag, Node
from .errors import Loc
from .model import Model

INF = float("inf")


@dataclass
class Primitive:
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
    dag = model.dag
    caps = _relations_to_caps(dag)  # may add `sub` nodes for inequalities
    _complete_rotations(dag)
    n = len(dag.nodes)
    live = _live_nodes(dag, [c.lhs for c in dag.constraints] + [c.rhs for c in dag.constraints]
                       + [c[0] for c in caps] + [v.node for v in dag.variables.values()])
    locs = _node_locations(dag, caps)
    uf = _UnionFind(n)
    for c in dag.constraints:
        if c.rel == "==":
            uf.union(c.lhs, c.rhs)
    _congruence_closure(dag, live, uf)
    slot_of, slots = _make_slots(dag, live, uf, caps)
    prims = _make_primitives(dag, live, slot_of, locs)
    _name_temporaries(slots, prims)
    return slots, prims


def _relations_to_caps(dag: Dag) -> list[tuple[int, float, float, Loc | None]]:
    """Domain caps (node, lo, hi, loc): inequalities on `lhs - rhs`."""
    caps = []
    for c in dag.constraints:
        if c.rel == "<=":
            caps.append((dag.op("sub", c.lhs, c.rhs), -INF, 0.0, c.loc))
        elif c.rel == ">=":
            caps.append((dag.op("sub", c.lhs, c.rhs), 0.0, INF, c.loc))
    return caps


def _complete_rotations(dag: Dag) -> None:
    """A rotation is one primitive with two outputs: make sure both output nodes exist."""
    for node in list(dag.nodes):
        if node.op in ("rotu", "rotv"):
            dag.op("rotv" if node.op == "rotu" else "rotu", *node.args)


def _live_nodes(dag: Dag, roots: list[int]) -> np.ndarray:
    live = np.zeros(len(dag.nodes), dtype=bool)
    live[roots] = True
    for i in range(len(dag.nodes) - 1, -1, -1):  # ids are topological: one reverse pass
        if live[i]:
            node = dag.nodes[i]
            for a in node.args:
                live[a] = True
            if node.op in ("rotu", "rotv"):
                live[dag._table[Node("rotv" if node.op == "rotu" else "rotu", node.args)]] = True
    # a sibling found late may reach further nodes: its args are earlier, handled by the pass
    return live


def _node_locations(dag: Dag, caps: list) -> list[Loc | None]:
    """Each node takes the location of the first constraint that reaches it."""
    locs: list[Loc | None] = [None] * len(dag.nodes)
    seen = np.zeros(len(dag.nodes), dtype=bool)
    roots = [(c.lhs, c.loc) for c in dag.constraints] + [(c.rhs, c.loc) for c in dag.constraints]
    roots += [(c[0], c[3]) for c in caps]
    for root, loc in roots:
        stack = [root]
        while stack:
            i = stack.pop()
            if seen[i]:
                continue
            seen[i] = True
            locs[i] = loc
            stack.extend(dag.nodes[i].args)
    return locs


def _op_key(node: Node) -> tuple:
    op = "rot" if node.op in ("rotu", "rotv") else node.op
    return op, node.data


def _congruence_closure(dag: Dag, live: np.ndarray, uf: _UnionFind) -> None:
    """Merge the outputs of primitives that became identical after merging their inputs."""
    ops = [i for i in np.flatnonzero(live) if dag.nodes[i].op not in ("const", "var")]
    changed = True
    while changed:
        changed = False
        seen: dict[tuple, int] = {}
        for i in ops:
            node = dag.nodes[i]
            args = tuple(uf.find(a) for a in node.args)
            if node.op in ("add", "mul"):
                args = tuple(sorted(args))
            key = (node.op, args, node.data)
            other = seen.setdefault(key, int(i))
            if other != i and uf.union(other, int(i)):
                changed = True


def _make_slots(dag: Dag, live: np.ndarray, uf: _UnionFind, caps: list):
    order: dict[int, int] = {}
    declared = [v for v in dag.variables.values()]
    for v in declared:  # declared unknowns first, in declaration order
        order.setdefault(uf.find(v.node), len(order))
    for i in np.flatnonzero(live):
        order.setdefault(uf.find(int(i)), len(order))
    m = len(order)
    lo, hi = np.full(m, -INF), np.full(m, INF)
    names = [""] * m
    kinds = ["temp"] * m
    origin: list[Loc | None] = [None] * m
    slot_of = np.full(len(dag.nodes), -1, dtype=np.int64)
    for i in np.flatnonzero(live):
        slot_of[i] = order[uf.find(int(i))]
    # a constant stated equal to something: an empty slot is that constraint's fault
    const_loc = {side: c.loc for c in dag.constraints for side in (c.lhs, c.rhs)
                 if dag.nodes[side].op == "const"}
    for i in np.flatnonzero(live):  # constants: the slot is that value
        node = dag.nodes[i]
        if node.op == "const":
            s = slot_of[i]
            _narrow(lo, hi, origin, s, node.data[0], node.data[1], const_loc.get(int(i)))
            if kinds[s] == "temp":
                kinds[s], names[s] = "const", format_const(*node.data)
    for v in reversed(declared):  # first declared name wins the slot's name
        s = slot_of[v.node]
        _narrow(lo, hi, origin, s, v.lo, v.hi, v.loc)
        names[s], kinds[s] = v.name, v.kind
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


def _make_primitives(dag: Dag, live: np.ndarray, slot_of: np.ndarray, locs) -> list[Primitive]:
    level = np.zeros(len(dag.nodes), dtype=np.int64)
    prims: list[Primitive] = []
    done: set[tuple] = set()
    for i in range(len(dag.nodes)):
        node = dag.nodes[i]
        if node.args:
            level[i] = 1 + max(level[a] for a in node.args)
        if not live[i] or not node.args:
            continue
        args = tuple(int(slot_of[a]) for a in node.args)
        if node.op in ("rotu", "rotv"):
            u = dag._table[Node("rotu", node.args)]
            v = dag._table[Node("rotv", node.args)]
            out: tuple[int, ...] = (int(slot_of[u]), int(slot_of[v]))
            op = "rot"
        else:
            out, op = (int(slot_of[i]),), node.op
        key = (op, out, args, node.data)
        if key in done:  # identical after merging (congruence closure)
            continue
        done.add(key)
        param = None if node.data is None else float(node.data)
        prims.append(Primitive(op, out, args, param, locs[i], int(level[i])))
    return prims


def _name_temporaries(slots: Slots, prims: list[Primitive]) -> None:
    count = 0
    for p in prims:
        for s in p.out:
            if slots.kinds[s] == "temp" and not slots.names[s]:
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
