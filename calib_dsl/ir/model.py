"""What elaboration hands to the compiler: the DAG with its variables and constraints,
plus the measurement tables the model read (or, in simulation mode, will write)."""

from __future__ import annotations

from dataclasses import dataclass, field

from calib_dsl.frontend.diagnostics import Loc
from calib_dsl.ir.dag import Dag


@dataclass
class Column:
    name: str
    tol: float  # error bound: the measured value is known to +- tol
    sim: tuple[float, float] | None = None  # simulate: draw uniformly in [lo, hi] (an input)


@dataclass
class Table:
    name: str
    path: str  # CSV path as resolved (relative to the model file, or --data)
    columns: list[Column]
    rows: int
    loc: Loc | None = None


@dataclass
class Model:
    path: str
    dag: Dag
    tables: list[Table] = field(default_factory=list)
    formulation: str = "matrix"  # "matrix" | "rotation"
    # Simulation mode only: a data cell `table.col[row]` is a `data` variable of the DAG.
    simulation: bool = False
