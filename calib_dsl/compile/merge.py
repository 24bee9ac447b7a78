"""The DAG as arrays, and the merging of its nodes into slots: union-find over the
constraints' two sides, then congruence closure (two primitives that became identical are
merged too), so common subexpressions stay shared after unification.
"""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np

from calib_dsl.frontend.diagnostics import Loc
from calib_dsl.ir.dag import TERNARY, Dag, Node


class UnionFind:
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


class DagArrays:
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
        rot = [codes[o] for o in TERNARY if o in codes]
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


def live_nodes(dag: Dag, g: DagArrays, roots: list[int]) -> np.ndarray:
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


def node_locations(dag: Dag, g: DagArrays, caps: list, cap_owner: list[int]
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


def congruence_closure(g: DagArrays, live: np.ndarray, rep: np.ndarray) -> np.ndarray:
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


def first_of_each(keys: np.ndarray) -> np.ndarray | None:
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
