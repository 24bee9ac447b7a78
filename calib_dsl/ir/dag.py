"""The expression DAG: hash-consed nodes, so a sub-expression is one node wherever it appears.

Nodes are created bottom-up (arguments always exist first), so node ids are a topological order.
Constants are intervals (a decimal literal or `pi` is enclosed, not rounded), and operations
on constants are folded with outward-rounded interval arithmetic: folding never loses a value.
"""

from __future__ import annotations

import copy
import gc
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from calib_dsl.arith.exact import enclose_decimal
from calib_dsl.arith.projections import forward
from calib_dsl.frontend.diagnostics import Loc

UNARY = ("neg", "sqr", "sqrt", "exp", "log", "sin", "cos", "tan", "abs", "pow")
BINARY = ("add", "sub", "mul", "div", "atan2")
COMMUTATIVE = ("add", "mul")
_SIMPLIFIED = frozenset(("add", "sub", "mul", "div", "neg"))  # what _simplify looks at
# `rotu`/`rotv` are the two outputs of one rotation primitive rot(beta, u, v):
#   rotu = u cos(beta) - v sin(beta),  rotv = u sin(beta) + v cos(beta).
TERNARY = ("rotu", "rotv")
ARITY = {**{op: 1 for op in UNARY}, **{op: 2 for op in BINARY}, **{op: 3 for op in TERNARY}}


class Node(NamedTuple):
    """One DAG node, immutable. A named tuple: hashing and comparing it (the hash-consing
    table's keys) run in C, and a plain `(op, args, data)` tuple finds it in the table."""

    op: str  # "const", "var", or a key of ARITY
    args: tuple[int, ...] = ()
    data: Any = None  # const: (lo, hi); var: name; pow: integer exponent


_new_node = tuple.__new__


@dataclass
class Variable:
    """A declared unknown (`param` or `var`) or, in simulation mode, a data cell (`data`)."""

    name: str
    lo: float
    hi: float
    loc: Loc | None
    node: int
    kind: str = "param"
    true: float | None = None
    true_stated: bool = False  # `true v` written (else `true` is a `c +- w` domain's centre)
    # `param x in lsq(start) +- w`: the domain is to be centred on a least-squares estimate
    # of the data at hand, as (start, w); [lo, hi] is unbounded until then
    prior: tuple[float, float] | None = None
    # the model's unit for it where a robot frame says which dimension it has (a length or
    # an angle entry, or a tool point's coordinate); None when nothing says
    unit: str | None = None


@dataclass
class Constraint:
    """`lhs rel rhs` with rel in `==`, `<=`, `>=`; loc is where the user stated it."""

    lhs: int
    rel: str
    rhs: int
    loc: Loc | None
    # implied by the model's other constraints (an orientation's matrix by its three angles,
    # elaborate/orientation.py): it contracts, but a point proof need not prove it
    implied: bool = False


@dataclass
class Dag:
    nodes: list[Node] = field(default_factory=list)
    variables: dict[str, Variable] = field(default_factory=dict)
    constraints: list[Constraint] = field(default_factory=list)
    # Measured cells: constant node -> the (table, column, row) it was read from. Equal
    # constants share a node, so a node may have several.
    cells: dict[int, set[tuple[str, str, int]]] = field(default_factory=dict)
    _table: dict[tuple, int] = field(default_factory=dict)
    # Per node, kept in step with `nodes` by _intern and _new (and `cell`): the value of a
    # point constant (else None), whether the node may be folded (`_foldable`), and its level
    # (0 for a leaf, else 1 + the highest level of its arguments).
    _points: list[float | None] = field(default_factory=list, repr=False)
    _folds: list[bool] = field(default_factory=list, repr=False)
    _levels: list[int] = field(default_factory=list, repr=False)
    # What builders derive from the DAG and may ask for again (nodes never change, so an
    # entry stays valid as long as the DAG): e.g. the robot layer's chain matrices.
    memo: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)
    # Every measured cell a node of its own that is never folded, exact ones too (equal exact
    # readings of two rows otherwise share a node, and a reading of 0 folds sin(q) away):
    # for callers that need every row's part of the program alike and depending on that
    # row's cells only (plan's rows by configuration).
    distinct_cells: bool = False

    def __post_init__(self) -> None:
        for i, node in enumerate(self.nodes):  # a DAG built from given nodes
            self._table.setdefault(node, i)
            self._note(i, node)

    # -- leaves -----------------------------------------------------------------------------
    def _intern(self, node: Node) -> int:
        found = self._table.get(node)
        if found is None:
            found = len(self.nodes)
            self.nodes.append(node)
            self._table[node] = found
            self._note(found, node)
        return found

    def _note(self, i: int, node: Node) -> None:
        const = node.op == "const"
        point = float(node.data[0]) if const and node.data[0] == node.data[1] else None
        self._points.append(point)
        self._folds.append(const and (i not in self.cells or point is not None))
        self._levels.append(1 + max(self._levels[a] for a in node.args) if node.args else 0)

    def const(self, lo: float, hi: float | None = None, unique: bool = False) -> int:
        """A constant interval [lo, hi] (a point when hi is omitted). `unique`: an uncertain
        quantity of its own (a measured value, a `value +- tol`), never shared with an equal
        interval written elsewhere: two readings of 0.5 +- 1e-5 are two different numbers."""
        hi = lo if hi is None else hi
        if unique and lo != hi:
            return self._intern(Node("const", (), (float(lo) + 0.0, float(hi) + 0.0,
                                                   len(self.nodes))))
        return self._intern(Node("const", (), (float(lo) + 0.0, float(hi) + 0.0)))

    def literal(self, text: str) -> int:
        """A decimal literal, enclosed exactly: `0.1` becomes the two floats around 1/10."""
        return self.const(*enclose_decimal(text))

    def cell(self, lo: float, hi: float, table: str, column: str, row: int) -> int:
        """A measured value [lo, hi], remembered as table.column[row] (for the tight strategy,
        which linearizes in the measurement errors of one configuration at a time)."""
        if self.distinct_cells and lo == hi:  # as an uncertain value: every row alike
            node = self._intern(Node("const", (), (float(lo) + 0.0, float(hi) + 0.0,
                                                   len(self.nodes))))
            self._points[node] = None
        else:
            node = self.const(lo, hi, unique=True)
        self.cells.setdefault(node, set()).add((table, column, row))
        self._folds[node] = self._points[node] is not None  # uncertain: never folded
        return node

    def with_cells(self, values: dict[int, tuple[float, float]]) -> Dag:
        """A copy in which these measured cells (uncertain constants, never folded nor
        shared) hold other values: every other node, and every node's id, is the same."""
        out = copy.copy(self)
        out.nodes, out._table = list(self.nodes), dict(self._table)
        out._points, out._folds = list(self._points), list(self._folds)
        out._levels = list(self._levels)
        for node, (lo, hi) in values.items():
            old = self.nodes[node]
            assert node in self.cells and old.op == "const" and len(old.data) == 3
            new = Node("const", (), (float(lo) + 0.0, float(hi) + 0.0, old.data[2]))
            del out._table[old]
            out.nodes[node] = new
            out._table[new] = node
        return out

    def pi(self) -> int:
        return self.const(np.nextafter(np.pi, -np.inf), np.nextafter(np.pi, np.inf))

    def var(self, name: str, lo: float, hi: float, loc: Loc | None = None, *,
            kind: str = "param", true: float | None = None) -> int:
        """Declare a named unknown with domain [lo, hi]; returns its node."""
        node = self._intern(Node("var", (), name))
        self.variables[name] = Variable(name, float(lo), float(hi), loc, node, kind, true)
        return node

    # -- operations -------------------------------------------------------------------------
    def op(self, op: str, *args: int, data: Any = None) -> int:
        """The node `op(args)`: folded if constant, simplified, shared if it exists."""
        if (op == "mul" or op == "add") and len(args) == 2 and data is None:
            # the bulk of a robot chain: two operands, neither a point constant (nothing to
            # simplify), not both foldable: just the sorted lookup of the general path below
            x, y = args
            points, folds = self._points, self._folds
            if points[x] is None and points[y] is None and not (folds[x] and folds[y]):
                if x > y:
                    x, y = y, x
                found = self._table.get((op, (x, y), None))
                return self._new(op, (x, y), None) if found is None else found
        if ARITY.get(op) != len(args):
            raise ValueError(f"{op} takes {ARITY.get(op)} arguments, got {len(args)}")
        if op == "pow":
            data = int(data)
            if data == 1:
                return args[0]
            if data == 0:
                return self.const(1.0)
            if data == 2:
                op, data = "sqr", None
        if op in _SIMPLIFIED:
            simple = self._simplify(op, args)
            if simple is not None:
                return simple
        folds = self._folds
        for a in args:
            if not folds[a]:
                break
        else:
            return self._fold(op, args, data)
        if op in COMMUTATIVE:
            if args[0] > args[1]:
                args = (args[1], args[0])
        found = self._table.get((op, args, data))
        return self._new(op, args, data) if found is None else found

    def _new(self, op: str, args: tuple[int, ...], data: Any) -> int:
        """Append the operation node op(args) (not in the table yet)."""
        node = _new_node(Node, (op, args, data))  # Node(op, args, data), minus a Python call
        found = len(self.nodes)
        self.nodes.append(node)
        self._table[node] = found
        self._points.append(None)
        self._folds.append(False)
        levels = self._levels
        if len(args) == 2:
            a, b = levels[args[0]], levels[args[1]]
            levels.append((a if a > b else b) + 1)
        else:
            levels.append(1 + max(levels[a] for a in args))
        return found

    def rot(self, beta: int, u: int, v: int) -> tuple[int, int]:
        """(u cos b - v sin b, u sin b + v cos b) as the two outputs of one rotation."""
        return self.op("rotu", beta, u, v), self.op("rotv", beta, u, v)

    def constrain(self, lhs: int, rel: str, rhs: int, loc: Loc | None = None,
                  implied: bool = False) -> None:
        if rel not in ("==", "<=", ">="):
            raise ValueError(f"unknown relation {rel!r}")
        self.constraints.append(Constraint(lhs, rel, rhs, loc, implied))

    # -- helpers ----------------------------------------------------------------------------
    def point(self, node: int) -> float | None:
        """The value of a point constant node, else None."""
        return self._points[node]

    def _foldable(self, node: int) -> bool:
        """A constant, but not an uncertain measured value: cos(q6) must stay a function of
        the measured q6, or a linearization could not follow its error."""
        return self._folds[node]

    def _simplify(self, op: str, args: tuple[int, ...]) -> int | None:
        # Exact identities only: they hold for every real value of the other operand.
        if op == "neg":
            inner = self.nodes[args[0]]
            if inner.op == "neg":
                return inner.args[0]
            return None
        p = (self._points[args[0]], self._points[args[1]])
        if p[0] is None and p[1] is None:
            return None
        if op == "add":
            if p[0] == 0.0:
                return args[1]
            if p[1] == 0.0:
                return args[0]
        elif op == "sub":
            if p[1] == 0.0:
                return args[0]
            if p[0] == 0.0:
                return self.op("neg", args[1])
        elif op == "mul":
            if p[0] == 0.0 or p[1] == 0.0:
                return self.const(0.0)
            if p[0] == 1.0:
                return args[1]
            if p[1] == 1.0:
                return args[0]
            if p[0] == -1.0:
                return self.op("neg", args[1])
            if p[1] == -1.0:
                return self.op("neg", args[0])
        elif op == "div":
            if p[1] == 1.0:
                return args[0]
        return None

    def _fold(self, op: str, args: tuple[int, ...], data: Any) -> int:
        boxes = [(np.array([self.nodes[a].data[0]]), np.array([self.nodes[a].data[1]]))
                 for a in args]
        param = None if data is None else np.array([float(data)])
        lo, hi = forward(op, boxes, param)
        return self.const(float(lo[0]), float(hi[0]))


@contextmanager
def paused_gc() -> Iterator[None]:
    """Run a block that builds many long-lived objects (DAG nodes, primitives) without the
    cyclic garbage collector, which would scan the growing heap again and again (they form
    no cycles); the collector is back, as it was, afterwards."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()

