"""The flat program's vocabulary: three-address primitives, the slots they read and write,
and the primitives as parallel arrays.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from calib_dsl.arith.interval import INF
from calib_dsl.frontend.diagnostics import Loc
from calib_dsl.ir.rows import Tiled


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

    # one entry per slot; a loop compiled once holds its rows' as ir/rows.Tiled (by template)
    names: list[str] | Tiled[str]
    kinds: list[str] | Tiled[str]  # "param" | "var" | "data" | "const" | "temp"
    lo: np.ndarray
    hi: np.ndarray
    # Where each slot's initial domain was last narrowed (declaration or constraint).
    origin: list[Loc | None] | Tiled[Loc | None]
    declared: list[int]  # slots of declared unknowns, in declaration order
    declared_names: list[str]
    # Measured cells: the configuration (table row) and table column a constant slot was read
    # from; -1 for other slots, -2 for a constant shared by several configurations.
    cell_row: np.ndarray | None = None
    cell_col: np.ndarray | None = None
    # (table name, model row k of `table.col[k]`) of each cell_row id
    row_keys: list[tuple[str, int]] | None = None
    col_keys: list[tuple[str, str]] | None = None  # (table name, column) of each cell_col id
    # the slots whose domain a measured value caps (`f == m.x[k]`): (cell_row, cell_col) ids
    measured_sides: dict[int, tuple[int, int]] | None = None
    # measured sides compared with cells of several table rows (`measured_sides` names one)
    capped_by_rows: set[int] = field(default_factory=set)
    # slots where an implied equality (ir/dag.Constraint.implied), and no other, meets two
    # computed sides: a point proof (analysis/certify_point.py) need not prove them equal
    implied: set[int] = field(default_factory=set)


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
