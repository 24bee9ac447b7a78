"""What elaboration hands to the compiler: the DAG with its variables and constraints,
plus the measurement tables the model read (or, in simulation mode, will write)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np

from calib_dsl.frontend.diagnostics import Loc
from calib_dsl.ir.dag import Dag


@dataclass
class Column:
    name: str
    tol: float  # error bound: the measured value is known to +- tol (in the model's units)
    sim: tuple[float, float] | None = None  # simulate: draw uniformly in [lo, hi] (an input)
    header: str | None = None  # its name in the file, when not `name`
    unit: str | None = None  # its unit in the file, when stated (converted to the model's)
    factor: tuple[float, float] = (1.0, 1.0)  # file unit -> model unit, an enclosure
    # not in the file: the sum of these columns (a measured side elaborate/measured.py made
    # one reading), each row's cell the sum of theirs rounded outward
    derived: tuple[str, ...] = ()


@dataclass
class Table:
    name: str
    path: str  # CSV path as resolved (relative to the model file, or --data)
    columns: list[Column]
    rows: int
    loc: Loc | None = None
    separator: str = ","
    decimal: str = "."
    # per row used: its line in the file and its data row number (1: the first after the
    # header); empty in simulation mode
    lines: list[int] = field(default_factory=list)
    numbers: list[int] = field(default_factory=list)
    # per column, each row's cell [lo, hi] in the model's units, its error bound included
    # (the DAG holds a node for the cells the model reads; empty in simulation mode)
    bounds: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    # per column, each row's reading [lo, hi] in the model's units, before its error bound
    readings: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    # the declaration selects rows itself (its `rows` or `exclude` option): another file
    # read as this table gets that selection too
    selects: bool = False


@dataclass
class Model:
    path: str
    dag: Dag
    tables: list[Table] = field(default_factory=list)
    formulation: str = "matrix"  # "matrix" | "rotation"
    # Simulation mode only: a data cell `table.col[row]` is a `data` variable of the DAG.
    simulation: bool = False
    consts: dict[str, Fraction] = field(default_factory=dict)  # top-level numeric consts
    batch: RowBatch | None = None  # a loop compiled once for all its rows
    sources: tuple[str, ...] = ()  # the files read: the model, then what it includes
    # (table, column) -> the limits of the robot joint its cells are the values of
    joint_limits: dict[tuple[str, str], tuple[float, float]] = field(default_factory=dict)
    # how many times `rows(t)` was evaluated: a model whose only use of a row count is its
    # batch's loop `1..rows(t)` can lose rows without elaborating again (elaborate/subset.py)
    row_counts_read: int = 0
    # the top-level consts read only as the whole error bound of columns (`x, y : +- e`),
    # with those columns (table, column): setting one changes those cells alone
    tolerances: dict[str, list[tuple[str, str]]] = field(default_factory=dict)
    # the model's unit of each dimension ("length", "angle"); None where it states none
    units: dict[str, str] | None = None


@dataclass
class RowBatch:
    """A loop over table rows elaborated for two rows only (elaborate/batching.py): its body
    depends on its index k through the cells `table.column[k]` alone, so every row's part of
    the program is the first row's with that row's cells; compile/replicate.py builds it."""

    rows: list[int]  # the loop's index values k, in order
    template: tuple[int, int]  # the two rows elaborated (the first two of `rows`)
    # (table, column) -> the bounds of each cell of the column (row k at index k - 1)
    cells: dict[tuple[str, str], tuple[np.ndarray, np.ndarray]]
    loc: Loc | None
    unrolled: Callable[[], Model]  # the same model elaborated with every loop unrolled
    # the table whose every row the loop runs over (`for k in 1..rows(t)`, reading cells of
    # t alone), else None
    table: str | None = None
