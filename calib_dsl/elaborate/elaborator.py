"""Elaboration: a `.cal` model (AST) becomes the expression DAG, its unknowns and constraints.

The work is shared by parts of one job each, joined in `Elaborator`: statements.py (files,
definitions, loops, declarations, constraints), expressions.py, loops.py (loops and sums
unrolled), robots.py, table_decl.py; the state they share is context.py's, what names
denote is scope.py's.

Everything that can be computed at compile time is: loops are unrolled, macros and `let`
aliases expanded inline, indices resolved, robot chains built (by `robot.forward_point`),
measurement tables read. What remains is DAG nodes and `dag.constrain` calls.

Values during elaboration are
- `Fraction`: an exact compile-time number (literals, loop indices, `rows(m)`, and `+ - * / ^`
  on them), turned into an enclosing DAG constant only when it meets an unknown;
- `int`: a DAG node id (an unknown, a data cell, an interval constant, an operation);
- a tuple of those: a vector.
Names may also denote a family of unknowns, a macro, a robot or a table (the `Entity` types).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from fractions import Fraction
from pathlib import Path
from typing import Any

from calib_dsl.elaborate.batching import Batching
from calib_dsl.elaborate.chains import FORMULATIONS
from calib_dsl.elaborate.context import DEFAULT_UNITS
from calib_dsl.elaborate.expressions import Expressions
from calib_dsl.elaborate.loops import Loops
from calib_dsl.elaborate.measured import Measured
from calib_dsl.elaborate.orientation import Orientation
from calib_dsl.elaborate.robots import Robots
from calib_dsl.elaborate.rows import Selection
from calib_dsl.elaborate.scope import (
    Entity,
    Macro,
    Scope,
)
from calib_dsl.elaborate.statements import Statements
from calib_dsl.elaborate.table_decl import Tables
from calib_dsl.elaborate.values import Values
from calib_dsl.frontend import ast
from calib_dsl.frontend.diagnostics import CalError, Loc
from calib_dsl.ir.dag import Dag
from calib_dsl.ir.model import Model, Table


# -- entry point ------------------------------------------------------------------------------
@dataclass(frozen=True)
class Inputs:
    """What the command line adds to a model: data files (or, from Python, `Values`) and row
    selections by table name ("" for the first table), and values of `const`s (`-D
    name=value`)."""

    data: Mapping[str, str | Path | Values] = field(default_factory=dict)
    rows: Mapping[str, Selection] = field(default_factory=dict)
    consts: Mapping[str, str] = field(default_factory=dict)
    unroll: bool = False  # every loop unrolled, none compiled once for all rows (--unroll)
    distinct_cells: bool = False  # exact cells never shared between rows (ir/dag.Dag)


def elaborate(path: str | Path, *, formulation: str = "matrix", data: str | Path | None = None,
              simulate_rows: int | None = None, inputs: Inputs | None = None) -> Model:
    """Elaborate the model file at `path` into a `Model` (DAG, unknowns, constraints, tables).

    `data` replaces the CSV file of the model's first table (as `inputs.data[""]`).
    `simulate_rows=N` is simulation mode: no CSV is read, each table has N rows, and each cell
    is a `data` variable of the DAG.
    """
    if formulation not in FORMULATIONS:
        raise CalError(f"unknown formulation '{formulation}' (expected matrix or rotation)")
    if simulate_rows is not None and simulate_rows < 1:
        raise CalError(f"simulation needs at least one row, not {simulate_rows}")
    inputs = inputs or Inputs()
    if data is not None:
        inputs = replace(inputs, data={**inputs.data, "": data})
    run = Elaborator(formulation, inputs, simulate_rows)
    run.unrolled_model = lambda: elaborate(path, formulation=formulation,
                                           inputs=replace(inputs, unroll=True))
    try:
        run.file(str(path))
    except RecursionError:
        raise CalError("the model nests too deeply to elaborate", None) from None
    _check_used(inputs, run)
    if not run.dag.variables and not run.dag.constraints:
        raise CalError("the model is empty: it declares no unknown and states no constraint, "
                       "so there is nothing to compile or solve", Loc(str(path), 1, 1))
    return Model(path=str(path), dag=run.dag, tables=run.tables, formulation=formulation,
                 simulation=simulate_rows is not None, consts=dict(run.const_values),
                 batch=run.batch, sources=tuple(run.sources),
                 joint_limits=dict(run.joint_limits),
                 units=dict(run.units) if run.units_loc else None,
                 row_counts_read=run.row_counts_read,
                 tolerances={c: cols for c, (n, cols) in run.tolerance_of.items()
                             if n == run.const_reads.get(c)})


def _check_used(inputs: Inputs, run: Elaborator) -> None:
    """Every table and const the command line named exists: a typo is an error, never
    silently ignored."""
    tables = [t.name for t in run.tables]
    for what, named in (("a data file", inputs.data), ("a row selection", inputs.rows)):
        for name, value in named.items():
            if name == "" and not tables:
                raise CalError(f"{what} ({value}) was given, but the model declares no table")
            if name and name not in tables:
                raise CalError(f"{what} was given for table '{name}', but the model has "
                               f"{'tables ' + ', '.join(tables) if tables else 'no table'}")
    unknown = sorted(set(inputs.consts) - run.overridden)
    if unknown:
        consts = sorted(run.consts_seen) or ["none"]
        raise CalError(f"-D {unknown[0]}=...: the model has no const '{unknown[0]}' (its "
                       f"consts: {', '.join(consts)})")


class Elaborator(Statements, Expressions, Loops, Batching, Robots, Tables, Measured,
                 Orientation):
    """One elaboration: the shared state, and each AST node type's part."""

    def __init__(self, formulation: str, inputs: Inputs, simulate_rows: int | None) -> None:
        self.dag = Dag(distinct_cells=inputs.distinct_cells)
        self.formulation = formulation
        self.data = dict(inputs.data)
        self.selections = dict(inputs.rows)
        self.overrides = dict(inputs.consts)
        self.overridden: set[str] = set()
        self.consts_seen: set[str] = set()
        self.row_counts_read = 0
        self.const_reads: dict[str, int] = {}
        self.tolerance_of: dict[str, tuple[int, list[tuple[str, str]]]] = {}
        self.const_values: dict[str, Fraction] = {}
        self.loop_product = 1  # the enclosing loops' iterations, multiplied
        self.unroll = inputs.unroll
        self.batch = None
        self.expanded: dict[tuple, tuple[Any, Any]] = {}  # macro calls made, by their values
        self.units = dict(DEFAULT_UNITS)
        self.units_loc: Loc | None = None
        self.simulate_rows = simulate_rows
        self.tables: list[Table] = []
        self.derived_columns: dict[tuple[str, str], Sequence[int]] = {}
        self.negated_cells: dict[int, int] = {}
        self.rotations: set[tuple[int, ...]] = set()
        self.euler_angles: dict[tuple[int, ...], tuple[int, ...]] = {}
        self.globals = Scope()
        self.including: list[tuple[Path, str]] = []  # the include stack (resolved, as shown)
        self.included: set[Path] = set()
        self.sources: list[str] = []
        self.expanding: list[Macro] = []
        self._consts: dict[Fraction, int] = {}
        # Robot uses are pure functions of their arguments: computed once each.
        self._robot_frames: dict[tuple, list[Any]] = {}
        self._robot_calls: dict[tuple, tuple[int, ...]] = {}
        self.joint_limits: dict[tuple[str, str], tuple[float, float]] = {}
        self._stmts: dict[type, Callable[[Any, Scope, bool], None]] = {
            ast.Const: self._const, ast.Let: self._let, ast.Def: self._def,
            ast.Decl: self._decl, ast.For: self._for, ast.Include: self._include,
            ast.Constraint: self._constraint, ast.Robot: self._robot,
            ast.TableDecl: self._table, ast.Units: self._units,
        }
        self._exprs: dict[type, Callable[[Any, Scope], Entity]] = {
            ast.Number: lambda e, s: e.value, ast.Pi: lambda e, s: self.dag.pi(),
            ast.Infinity: self._infinity, ast.Name: self._name, ast.Neg: self._neg,
            ast.BinOp: self._binop, ast.Call: self._call, ast.RobotAt: self._robot_at,
            ast.RobotAxes: self._robot_axes,
            ast.Index: self._index, ast.Field: self._field, ast.TupleLit: self._tuple,
            ast.IntervalLit: self._interval, ast.SumOver: self._sum_over,
        }
