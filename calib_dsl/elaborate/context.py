"""The state an elaboration carries, shared by its parts (statements, expressions, robots,
tables): each part is a class of its own module over this state, and `Elaborator` joins them.
The methods one part calls on another are declared here for the type checker only."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, Any

from calib_dsl.elaborate.rows import Selection
from calib_dsl.elaborate.scope import Entity, Macro, Scalar, Scope, Value
from calib_dsl.elaborate.values import Values
from calib_dsl.frontend import ast
from calib_dsl.frontend.diagnostics import Loc
from calib_dsl.ir.dag import Dag
from calib_dsl.ir.model import Table

DEFAULT_UNITS = {"length": "m", "angle": "rad"}


class Context:
    dag: Dag
    formulation: str
    # files replacing tables' (--data), or values (the Python API's), by table ("": the first)
    data: dict[str, str | Path | Values]
    selections: dict[str, Selection]  # rows to use (--rows), by table ("": the first)
    overrides: dict[str, str]  # const values from the command line (-D name=value)
    overridden: set[str]  # the consts they replaced
    consts_seen: set[str]
    row_counts_read: int  # how many times `rows(t)` was evaluated
    const_reads: dict[str, int]  # how many times each top-level const's value was read
    # the columns each top-level const is the whole tolerance of (`x, y : +- e`), and how
    # many of its reads those were
    tolerance_of: dict[str, tuple[int, list[tuple[str, str]]]]
    const_values: dict[str, Fraction]  # the top-level numeric consts, as elaborated
    loop_product: int
    expanded: dict[tuple, tuple[Any, Any]]
    units: dict[str, str]  # the model's unit of each dimension ("length", "angle")
    units_loc: Loc | None  # where the model stated them
    simulate_rows: int | None  # simulation mode: this many rows, no file read
    tables: list[Table]
    # (table, column) -> the cells of a column derived from others (elaborate/measured.py)
    derived_columns: dict[tuple[str, str], Sequence[int]]
    negated_cells: dict[int, int]  # the constant -c of an exact cell c's node -> c's node
    # 9-vectors that are rotations by construction; those made by euler_xyz, by their angles
    # (elaborate/orientation.py)
    rotations: set[tuple[int, ...]]
    euler_angles: dict[tuple[int, ...], tuple[int, ...]]
    globals: Scope
    including: list[tuple[Path, str]]  # the include stack (resolved, as shown)
    included: set[Path]
    sources: list[str]  # every file read, as shown, the model first (provenance)
    expanding: list[Macro]  # the macros being expanded (recursion is an error)
    _consts: dict[Fraction, int]
    _robot_frames: dict[tuple, list[Any]]
    _robot_calls: dict[tuple, tuple[int, ...]]
    joint_limits: dict[tuple[str, str], tuple[float, float]]
    _stmts: dict[type, Callable[[Any, Scope, bool], None]]
    _exprs: dict[type, Callable[[Any, Scope], Entity]]

    if TYPE_CHECKING:  # what the parts call on each other
        def file(self, shown: str) -> None: ...
        def block(self, stmts: tuple[ast.Stmt, ...], scope: Scope, top: bool) -> None: ...
        def _top_only(self, what: str, loc: Loc, top: bool) -> None: ...
        def domain(self, e: ast.Expr | None, scope: Scope
                   ) -> tuple[float, float, float | None]: ...
        def entity(self, e: ast.Expr, scope: Scope) -> Entity: ...
        def value(self, e: ast.Expr, scope: Scope) -> Value: ...
        def node(self, v: Scalar, loc: Loc) -> int: ...
        def scalar(self, v: Value, loc: Loc, what: str) -> Scalar: ...
        def constant_interval(self, v: Value, loc: Loc, what: str) -> tuple[float, float]: ...
        def integer(self, e: ast.Expr, scope: Scope, what: str, hint: str = "") -> int: ...
        def arith(self, op: str, a: Scalar, b: Scalar, loc: Loc) -> Scalar: ...
        def unrolled(self, var: ast.Ident, rng: ast.Range, scope: Scope, loc: Loc, what: str,
                     body: Callable[[Scope], Any]) -> list[Any]: ...
        def is_constant(self, v: Scalar) -> bool: ...
        def batched(self, s: ast.For, scope: Scope) -> bool: ...
        def interval_bounds(self, e: ast.IntervalLit, scope: Scope) -> tuple[float, float]: ...
        def lookup(self, name: str, loc: Loc, scope: Scope) -> Entity: ...
        def is_global_const(self, name: str, hit: tuple[Entity, Loc] | None) -> bool: ...
        def _robot_at(self, e: ast.RobotAt, scope: Scope) -> tuple[int, ...]: ...
        def _robot_axes(self, e: ast.RobotAxes, scope: Scope) -> tuple[int, ...]: ...
        def _robot(self, s: ast.Robot, scope: Scope, top: bool) -> None: ...
        def _table(self, s: ast.TableDecl, scope: Scope, top: bool) -> None: ...
        def measured_pair(self, lhs: int, rhs: int) -> tuple[int, int] | None: ...
        def note_rotation(self, value: tuple[int, ...], angles: tuple[int, ...] | None = None
                          ) -> tuple[int, ...]: ...
        def is_rotation(self, value: Value) -> bool: ...
        def orientation_pairs(self, lhs: Value, rhs: Value) -> list[tuple[int, int]] | None: ...
