"""What names denote during elaboration, and the lexical scopes that hold them.

Values are
- `Fraction`: an exact compile-time number (literals, loop indices, `rows(m)`, and `+ - * / ^`
  on them), turned into an enclosing DAG constant only when it meets an unknown;
- `int`: a DAG node id (an unknown, a data cell, an interval constant, an operation);
- a tuple of those: a vector.
Names may also denote a family of unknowns, a macro, a robot or a table (the `Entity` types).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Union

from calib_dsl.frontend import ast
from calib_dsl.frontend.diagnostics import CalError, Loc

# Built-in functions: name -> (number of arguments, DAG op).
FUNCTIONS = {"sqr": 1, "sqrt": 1, "exp": 1, "log": 1, "sin": 1, "cos": 1, "tan": 1, "abs": 1,
             "atan2": 2}


# Functions of vectors; a rotation is a 9-vector, its matrix row by row.
SPECIAL = {"rows": 1, "dot": 2, "euler_xyz": 3, "compose": 2}


BUILTINS = set(FUNCTIONS) | set(SPECIAL)


Scalar = Union[Fraction, int]  # noqa: UP007 - an alias used at run time too


Value = Union[Fraction, int, tuple[Scalar, ...]]  # noqa: UP007


# -- what names denote ------------------------------------------------------------------------
@dataclass(frozen=True)
class Family:
    """An indexed family of declared unknowns, possibly with its first indices given."""

    name: str
    dims: tuple[tuple[int, int], ...]  # (first, last) index of each dimension
    nodes: dict[tuple[int, ...], int]
    prefix: tuple[int, ...] = ()


@dataclass(frozen=True)
class Macro:
    name: str
    params: tuple[ast.Ident, ...]
    body: ast.Expr
    scope: Scope


@dataclass(frozen=True)
class RobotDef:
    name: str
    params: tuple[ast.Ident, ...]
    base: tuple[ast.FrameDecl, ...]  # composed in order, before the joints
    joints: tuple[ast.FrameDecl, ...]
    tool: tuple[ast.FrameDecl, ...]  # composed in order, after the joints
    convention: str  # of the joints: "mdh" or "dh"
    scope: Scope
    limits: tuple[tuple[float, float] | None, ...] = ()  # per joint variable (None: none)


@dataclass(frozen=True)
class TableRef:
    name: str
    rows: int
    cells: dict[str, Sequence[int]]  # column -> node of each row (row k at index k - 1)


@dataclass(frozen=True)
class ColumnRef:
    table: TableRef
    column: str


Entity = Union[Fraction, int, tuple, Family, Macro, RobotDef, TableRef, ColumnRef]  # noqa: UP007


class Scope:
    """Lexical scope: a name is defined once per scope; inner scopes may shadow outer names."""

    __slots__ = ("names", "parent")

    def __init__(self, parent: Scope | None = None) -> None:
        self.names: dict[str, tuple[Entity, Loc]] = {}
        self.parent = parent

    def lookup(self, name: str) -> tuple[Entity, Loc] | None:
        scope: Scope | None = self
        while scope is not None:
            hit = scope.names.get(name)
            if hit is not None:
                return hit
            scope = scope.parent
        return None

    def check_new(self, ident: ast.Ident) -> None:
        if ident.id in BUILTINS:
            raise CalError(f"'{ident.id}' is a built-in function: choose another name", ident.loc)
        old = self.names.get(ident.id)
        if old is not None:
            raise CalError(f"'{ident.id}' is already defined (at {old[1]})", ident.loc)

    def define(self, ident: ast.Ident, entity: Entity) -> None:
        self.check_new(ident)
        self.names[ident.id] = (entity, ident.loc)

    def visible(self) -> set[str]:
        out: set[str] = set()
        scope: Scope | None = self
        while scope is not None:
            out.update(scope.names)
            scope = scope.parent
        return out
