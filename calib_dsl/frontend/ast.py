"""The AST of a `.cal` file: what the parser builds and the elaborator walks.

Every node carries the `Loc` where it starts (file, 1-based line and column), so that any
error found later points at the user's text. Numbers are kept exact (`Fraction`).
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

from calib_dsl.frontend.diagnostics import Loc

# -- expressions --------------------------------------------------------------------------


@dataclass(frozen=True)
class Number:
    value: Fraction  # the exact value of the decimal literal
    text: str
    loc: Loc


@dataclass(frozen=True)
class Pi:
    loc: Loc


@dataclass(frozen=True)
class Infinity:
    """`oo`: only meaningful as a bound of an interval or domain."""

    loc: Loc


@dataclass(frozen=True)
class Name:
    id: str
    loc: Loc


@dataclass(frozen=True)
class Neg:
    arg: Expr
    loc: Loc


@dataclass(frozen=True)
class BinOp:
    """`op` is one of `+ - * / ^ +-`."""

    op: str
    left: Expr
    right: Expr
    loc: Loc


@dataclass(frozen=True)
class Call:
    func: str
    args: tuple[Expr, ...]
    loc: Loc


@dataclass(frozen=True)
class RobotAt:
    """`robot(joint values) at point`: workshop coordinates of a tool point."""

    robot: str
    args: tuple[Expr, ...]
    point: Expr
    loc: Loc


@dataclass(frozen=True)
class RobotAxes:
    """`robot(joint values) axes`: the last frame's orientation in the workshop frame, a
    9-vector (the rotation matrix row by row)."""

    robot: str
    args: tuple[Expr, ...]
    loc: Loc


@dataclass(frozen=True)
class Index:
    base: Expr
    index: Expr
    loc: Loc


@dataclass(frozen=True)
class Field:
    """`table.column` (then indexed by a row)."""

    base: Expr
    name: str
    loc: Loc


@dataclass(frozen=True)
class TupleLit:
    items: tuple[Expr, ...]
    loc: Loc


@dataclass(frozen=True)
class IntervalLit:
    lo: Expr
    hi: Expr
    loc: Loc


@dataclass(frozen=True)
class SumOver:
    """`sum(var in range) body`: the body's values for each integer of the range, added."""

    var: Ident
    range: Range
    body: Expr
    loc: Loc


Expr = (Number | Pi | Infinity | Name | Neg | BinOp | Call | RobotAt | RobotAxes | Index | Field
        | TupleLit | IntervalLit | SumOver)

# -- statements ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Ident:
    """A name where it is defined (for duplicate-name errors)."""

    id: str
    loc: Loc


@dataclass(frozen=True)
class Range:
    lo: Expr
    hi: Expr
    loc: Loc


@dataclass(frozen=True)
class Const:
    name: Ident
    value: Expr
    loc: Loc


@dataclass(frozen=True)
class Let:
    name: Ident
    value: Expr
    loc: Loc


@dataclass(frozen=True)
class Def:
    name: Ident
    params: tuple[Ident, ...]
    body: Expr
    loc: Loc


@dataclass(frozen=True)
class DeclName:
    name: Ident
    dims: tuple[Range, ...]


@dataclass(frozen=True)
class Decl:
    """`param ...;` or `var ...;` (kind), several names sharing a domain and true value."""

    kind: str
    names: tuple[DeclName, ...]
    domain: Expr | None
    true: Expr | None
    loc: Loc


@dataclass(frozen=True)
class For:
    var: Ident
    range: Range
    body: tuple[Stmt, ...]
    loc: Loc


@dataclass(frozen=True)
class Include:
    path: str
    loc: Loc


@dataclass(frozen=True)
class Constraint:
    lhs: Expr
    rel: str  # "==", "<=", ">=" (or "<", ">", "=", rejected with an explanation)
    rhs: Expr
    loc: Loc
    rel_loc: Loc


@dataclass(frozen=True)
class Entry:
    name: Ident
    value: Expr


@dataclass(frozen=True)
class FrameDecl:
    kind: str  # "base" | "joint" | "tool"
    entries: tuple[Entry, ...]
    loc: Loc


@dataclass(frozen=True)
class Robot:
    name: Ident
    params: tuple[Ident, ...]
    frames: tuple[FrameDecl, ...]
    loc: Loc
    convention: Ident | None = None  # of the joints: "mdh" (None) or "dh"
    limits: tuple[Expr | None, ...] = ()  # per joint variable: `q in [lo, hi]` (None: none)


@dataclass(frozen=True)
class ColumnGroup:
    names: tuple[Ident, ...]  # the model's names of the columns
    tol: Expr
    simulate: Expr | None
    loc: Loc
    headers: tuple[str | None, ...] = ()  # per name: the file's header (None: the name)
    units: tuple[Ident | None, ...] = ()  # per name: the file's unit (None: as the model's)


@dataclass(frozen=True)
class RowRange:
    first: Expr
    last: Expr | None  # None: to the last row
    step: Expr | None
    loc: Loc


@dataclass(frozen=True)
class TableOption:
    name: Ident
    value: str | Expr | RowRange
    loc: Loc


@dataclass(frozen=True)
class TableDecl:
    name: Ident
    path: str
    path_loc: Loc
    groups: tuple[ColumnGroup, ...]
    loc: Loc
    options: tuple[TableOption, ...] = ()


@dataclass(frozen=True)
class Units:
    names: tuple[Ident, ...]
    loc: Loc


Stmt = Const | Let | Def | Decl | For | Include | Constraint | Robot | TableDecl | Units
