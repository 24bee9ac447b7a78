"""The expression DAG: hash-consed nodes, so a sub-expression is one node wherever it appears.

Nodes are created bottom-up (arguments always exist first), so node ids are a topological order.
Constants are intervals (a decimal literal or `pi` is enclosed, not rounded), and operations
on constants are folded with outward-rounded interval arithmetic: folding never loses a value.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

import numpy as np

from .errors import Loc

UNARY = ("neg", "sqr", "sqrt", "exp", "log", "sin", "cos", "tan", "abs", "pow")
BINARY = ("add", "sub", "mul", "div", "atan2")
COMMUTATIVE = ("add", "mul")
# `rotu`/`rotv` are the two outputs of one rotation primitive rot(beta, u, v):
#   rotu = u cos(beta) - v sin(beta),  rotv = u sin(beta) + v cos(beta).
TERNARY = ("rotu", "rotv")
ARITY = {**{op: 1 for op in UNARY}, **{op: 2 for op in BINARY}, **{op: 3 for op in TERNARY}}


@dataclass(frozen=True)
class Node:
    op: str  # "const", "var", or a key of ARITY
    args: tuple[int, ...] = ()
    data: Any = None  # const: (lo, hi); var: name; pow: integer exponent


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


@dataclass
class Constraint:
    """`lhs rel rhs` with rel in `==`, `<=`, `>=`; loc is where the user stated it."""

    lhs: int
    rel: str
    rhs: int
    loc: Loc | None


@dataclass
class Dag:
    nodes: list[Node] = field(default_factory=list)
    variables: dict[str, Variable] = field(default_factory=dict)
    constraints: list[Constraint] = field(default_factory=list)
    # Measured cells: constant node -> the (table, column, row) it was read from. Equal
    # constants share a node, so a node may have several.
    cells: dict[int, set[tuple[str, str, int]]] = field(default_factory=dict)
    _table: dict[Node, int] = field(default_factory=dict)

    # -- leaves -----------------------------------------------------------------------------
    def _intern(self, node: Node) -> int:
        found = self._table.get(node)
        if found is None:
            found = len(self.nodes)
            self.nodes.append(node)
            self._table[node] = found
        return found

    def const(self, lo: float, hi: float | None = None) -> int:
        """A constant interval [lo, hi] (a point when hi is omitted)."""
        hi = lo if hi is None else hi
        return self._intern(Node("const", (), (float(lo) + 0.0, float(hi) + 0.0)))

    def literal(self, text: str) -> int:
        """A decimal literal, enclosed exactly: `0.1` becomes the two floats around 1/10."""
        return self.const(*enclose_decimal(text))

    def cell(self, lo: float, hi: float, table: str, column: str, row: int) -> int:
        """A measured value [lo, hi], remembered as table.column[row] (for the tight strategy,
        which linearizes in the measurement errors of one configuration at a time)."""
        node = self.const(lo, hi)
        self.cells.setdefault(node, set()).add((table, column, row))
        return node

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
        simple = self._simplify(op, args)
        if simple is not None:
            return simple
        if all(self._foldable(a) for a in args):
            return self._fold(op, args, data)
        if op in COMMUTATIVE:
            args = tuple(sorted(args))
        return self._intern(Node(op, tuple(args), data))

    def rot(self, beta: int, u: int, v: int) -> tuple[int, int]:
        """(u cos b - v sin b, u sin b + v cos b) as the two outputs of one rotation."""
        return self.op("rotu", beta, u, v), self.op("rotv", beta, u, v)

    def constrain(self, lhs: int, rel: str, rhs: int, loc: Loc | None = None) -> None:
        if rel not in ("==", "<=", ">="):
            raise ValueError(f"unknown relation {rel!r}")
        self.constraints.append(Constraint(lhs, rel, rhs, loc))

    # -- helpers ----------------------------------------------------------------------------
    def point(self, node: int) -> float | None:
        """The value of a point constant node, else None."""
        n = self.nodes[node]
        if n.op == "const" and n.data[0] == n.data[1]:
            return float(n.data[0])
        return None

    def _foldable(self, node: int) -> bool:
        """A constant, but not an uncertain measured value: cos(q6) must stay a function of
        the measured q6, or a linearization could not follow its error."""
        n = self.nodes[node]
        return n.op == "const" and (node not in self.cells or n.data[0] == n.data[1])

    def _simplify(self, op: str, args: tuple[int, ...]) -> int | None:
        # Exact identities only: they hold for every real value of the other operand.
        p = [self.point(a) for a in args]
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
        elif op == "neg":
            inner = self.nodes[args[0]]
            if inner.op == "neg":
                return inner.args[0]
        return None

    def _fold(self, op: str, args: tuple[int, ...], data: Any) -> int:
        from .projections import forward  # late import: projections is the arithmetic core

        boxes = [(np.array([self.nodes[a].data[0]]), np.array([self.nodes[a].data[1]]))
                 for a in args]
        param = None if data is None else np.array([float(data)])
        lo, hi = forward(op, boxes, param)
        return self.const(float(lo[0]), float(hi[0]))


def enclose_decimal(text: str) -> tuple[float, float]:
    """The smallest float interval holding the exact value of a decimal literal."""
    exact = Fraction(text)
    x = float(exact)
    if Fraction(x) == exact:
        return x, x
    if Fraction(x) < exact:
        return x, float(np.nextafter(x, np.inf))
    return float(np.nextafter(x, -np.inf)), x
