"""Simulated measurements by the paper's protocol (§4).

The model is elaborated in simulation mode: every table cell `table.col[row]` is a `data`
variable of the DAG. A column with `sim = (lo, hi)` is an INPUT, drawn uniformly in [lo, hi];
every other column is an OUTPUT, computed from its defining constraint (`cell == expr` or
`expr == cell`) with every parameter at its true value. Then every column, inputs too, gets
uniform noise in [-tol, +tol]: the recorded q is q + e_q, as an encoder reading would be.
A `Campaign` (campaign.py) chooses the poses' shape (random, a grid, repeated poses), adds a
smooth pose-dependent error of a given amplitude to the measured columns, and can leave out
their independent noise.

Random draws, in this order so a seed always gives the same file: the inputs, table by table,
column by column (declaration order), then the noise in the same order; the systematic
error's terms from a stream of their own.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from calib_dsl.elaborate.elaborator import Inputs, elaborate
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.ir.dag import Dag
from calib_dsl.ir.model import Model, Table
from calib_dsl.ir.status import SlotKind
from calib_dsl.progress import Progress
from calib_dsl.studies.campaign import PLAIN, Campaign, poses, systematic
from calib_dsl.studies.evaluate import Array, Evaluator

# A constraint that does not define a cell must hold at the true values, up to float error:
# otherwise the data would be inconsistent and calibration would answer "infeasible".
CHECK_RTOL = 1e-9
CHECK_ATOL = 1e-9
# The model is elaborated with a node per cell and operation of every row, each about half a
# kB: a campaign past this many nodes would take more than about 2 GB (a guard on the
# request: several files with their own seeds make a larger campaign)
MAX_NODES = 5_000_000


def simulate(model_path: str | Path, rows: int, seed: int, formulation: str = "matrix",
             out_csv: Path | None = None, progress: Progress | None = None,
             campaign: Campaign = PLAIN, consts: Mapping[str, str] | None = None) -> None:
    """Elaborate MODEL for `rows` configurations, simulate its tables, write the CSV.

    `out_csv` receives the model's table; without it each table goes to its own path.
    `progress` is told each stage as it ends (no width: there is no box). `consts` sets
    top-level consts (-D), as an error bound the noise is drawn within.
    """
    start = time.perf_counter()

    def done(stage: str) -> None:
        if progress is not None:
            progress(stage, None, time.perf_counter() - start)

    inputs = Inputs(consts=dict(consts or {}))
    _check_size(model_path, rows, formulation, inputs)
    model = elaborate(str(model_path), formulation=formulation, simulate_rows=rows,
                      inputs=inputs)
    if not model.tables:
        raise CalError("the model has no `table` to simulate")
    if out_csv is not None and len(model.tables) != 1:
        raise CalError(f"the model has {len(model.tables)} tables; simulate writes one CSV "
                       "per table, so give no output path", model.tables[-1].loc)
    done(f"elaborated for {rows:,} configurations")
    tables = simulate_model(model, seed, campaign)
    done("measurements computed")
    for table in model.tables:
        write_csv(Path(out_csv) if out_csv is not None else Path(table.path), table,
                  tables[table.name])
    done("written")


def _check_size(model_path: str | Path, rows: int, formulation: str, inputs: Inputs) -> None:
    """A user error where `rows` configurations would elaborate into more than MAX_NODES
    nodes (the nodes a row adds: the model elaborated for one row and for two)."""
    one, two = (len(elaborate(str(model_path), formulation=formulation, simulate_rows=k,
                              inputs=inputs).dag.nodes) for k in (1, 2))
    per_row = max(two - one, 1)
    if rows * per_row > MAX_NODES:
        raise CalError(f"simulate: {rows:,} configurations of {per_row} nodes each would not "
                       f"fit in memory (at most {MAX_NODES // per_row:,} for this model): "
                       "simulate several files with their own --seed")


def simulate_model(model: Model, seed: int, campaign: Campaign = PLAIN,
                   given: Mapping[str, Array] | None = None) -> dict[str, Array]:
    """The noisy measurements of every table: {table name: (rows, columns) array}. `given`
    holds, by table name, the true inputs (rows, input columns in declaration order, in the
    model's units) to measure at instead of drawing them (`simulate --at`)."""
    dag = model.dag
    rng = np.random.default_rng(seed)
    values = _true_parameters(dag)
    cells = {t.name: _cell_nodes(dag, t) for t in model.tables}
    drawn: dict[str, Array] = {}
    for t in model.tables:  # draw the inputs
        ins = [(col, nodes) for col, nodes in zip(t.columns, cells[t.name], strict=True)
               if col.sim is not None]
        if given is not None and t.name in given:
            drawn[t.name] = _given(given[t.name], t, len(ins))
        else:
            drawn[t.name] = poses(campaign, [col.sim for col, _ in ins if col.sim is not None],
                                  t.rows, rng)
        for (_, nodes), xs in zip(ins, drawn[t.name].T, strict=True):
            for node, x in zip(nodes, xs, strict=True):
                if node is not None:
                    values[node] = float(x)
    evaluator = Evaluator(dag)
    value = _solve_outputs(model, cells, values, evaluator)
    _check_constraints(dag, value)
    out: dict[str, Array] = {}
    errors = np.random.default_rng([seed, 1])  # the systematic error's own stream
    for t in model.tables:  # record, with noise
        table = np.empty((t.rows, len(t.columns)))
        for j, (col, nodes) in enumerate(zip(t.columns, cells[t.name], strict=True)):
            exact = np.array([np.nan if n is None else value[n] for n in nodes])
            noise = rng.uniform(-col.tol, col.tol, size=t.rows)
            if col.sim is None:  # a measured column: the campaign's errors
                if campaign.systematic > 0:
                    if drawn[t.name].shape[1] == 0:
                        raise CalError(f"table '{t.name}' has no input column (`simulate "
                                       "in`) for a systematic error to depend on", t.loc)
                    err = systematic(campaign.systematic, drawn[t.name].shape[1], errors)
                    exact = exact + err(drawn[t.name])
                if not campaign.noise:
                    noise = np.zeros(t.rows)
            table[:, j] = exact + noise
        out[t.name] = table
    return out


def _given(q: Array, t: Table, inputs: int) -> Array:
    q = np.asarray(q, dtype=float)
    if q.shape != (t.rows, inputs):
        raise ValueError(f"table '{t.name}': {q.shape} given inputs, for {t.rows} rows of "
                         f"{inputs} input columns")
    return q


def write_csv(path: Path, table: Table, data: Array) -> None:
    """The table as its declaration reads it: its separator, decimal mark, header names and
    units (values converted from the model's units); full-precision floats (repr)."""
    sep = table.separator
    lines = [sep.join(c.header or c.name for c in table.columns)]
    scale = np.array([0.5 * (c.factor[0] + c.factor[1]) for c in table.columns])
    for row in data:
        cells = [repr(float(x)) for x in np.asarray(row, dtype=float) / scale]
        if table.decimal == ",":
            cells = [c.replace(".", ",") for c in cells]
        lines.append(sep.join(cells))
    if str(path) == "-":  # standard output, as `--json -`
        sys.stdout.write("\n".join(lines) + "\n")
        sys.stdout.flush()
        return
    try:
        path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    except OSError as err:
        raise CalError(f"cannot write {path}: {err.strerror}", table.loc) from err


def cell_name(table: str, column: str, row: int) -> str:
    """The DAG variable of a cell in simulation mode (rows are 1-based)."""
    return f"{table}.{column}[{row}]"


# -- steps ----------------------------------------------------------------------------------
def _true_parameters(dag: Dag) -> dict[int, float]:
    values: dict[int, float] = {}
    for v in dag.variables.values():
        if v.kind == SlotKind.PARAM:
            if v.true is None:
                raise CalError(f"parameter '{v.name}' has no true value: simulation needs "
                               "one for every parameter (`param ... true VALUE;`)", v.loc)
            values[v.node] = float(v.true)
        elif v.kind != SlotKind.DATA and v.true is not None:
            values[v.node] = float(v.true)
    return values


def _cell_nodes(dag: Dag, t: Table) -> list[list[int | None]]:
    """cells[column][row - 1] = the cell's node (None: the model never mentions the cell)."""
    out = []
    for col in t.columns:
        nodes = []
        for row in range(1, t.rows + 1):
            v = dag.variables.get(cell_name(t.name, col.name, row))
            nodes.append(None if v is None else v.node)
        out.append(nodes)
    return out


def _solve_outputs(model: Model, cells: dict[str, list[list[int | None]]],
                   values: dict[int, float], evaluator: Evaluator) -> Array:
    """Evaluate; give each unknown cell the value of a defining `==`; repeat while it helps
    (an output may be defined through another output or an auxiliary `var`)."""
    dag = model.dag
    defs: dict[int, list[int]] = {}
    for c in dag.constraints:
        if c.rel == "==":
            defs.setdefault(c.lhs, []).append(c.rhs)
            defs.setdefault(c.rhs, []).append(c.lhs)
    unknown = set(_output_cells(model, cells, defs))
    unknown.update(v.node for v in dag.variables.values()
                   if v.kind not in (SlotKind.PARAM, SlotKind.DATA) and v.node not in values)
    while True:
        value = evaluator(values, default=math.nan)
        solved = [n for n in unknown if _define(n, defs, value, values)]
        unknown.difference_update(solved)
        if not solved:
            break
    for t in model.tables:
        for col, nodes in zip(t.columns, cells[t.name], strict=True):
            for row, cell in enumerate(nodes, start=1):
                if cell is not None and cell in unknown:
                    raise CalError(f"cannot compute {cell_name(t.name, col.name, row)} from "
                                   "the true values (a cycle, or a value out of the domain "
                                   "of a function)", t.loc)
    return value


def _output_cells(model: Model, cells: dict[str, list[list[int | None]]],
                  defs: dict[int, list[int]]) -> list[int]:
    out = []
    for t in model.tables:
        for col, nodes in zip(t.columns, cells[t.name], strict=True):
            if col.sim is not None:
                continue
            for row, n in enumerate(nodes, start=1):
                if n is None or n not in defs:
                    raise CalError(f"output column '{t.name}.{col.name}' has no defining "
                                   f"constraint (`cell == expression`) for "
                                   f"{cell_name(t.name, col.name, row)}, and no `sim` range "
                                   "to draw it from", t.loc)
                out.append(n)
    return out


def _define(node: int, defs: dict[int, list[int]], value: Array,
            values: dict[int, float]) -> bool:
    for expr in defs.get(node, ()):
        x = float(value[expr])
        if math.isfinite(x):
            values[node] = x
            return True
    return False


def _check_constraints(dag: Dag, value: Array) -> None:
    for c in dag.constraints:
        lhs, rhs = _side(dag, value, c.lhs), _side(dag, value, c.rhs)
        gap = {"==": max(lhs[0] - rhs[1], rhs[0] - lhs[1]),  # distance between the two sides
               "<=": lhs[0] - rhs[1], ">=": rhs[0] - lhs[1]}[c.rel]
        scale = max(abs(lhs[0]), abs(lhs[1]), abs(rhs[0]), abs(rhs[1]))
        if not gap <= CHECK_ATOL + CHECK_RTOL * scale:  # also catches nan
            raise CalError(f"this constraint does not hold at the true values "
                           f"({show(lhs)} {c.rel} {show(rhs)}): the simulated data would "
                           "be inconsistent", c.loc)


def _side(dag: Dag, value: Array, node: int) -> tuple[float, float]:
    # A constant side keeps its interval: `dist(b1, b2) == [0.17, 0.18]` is met inside it.
    n = dag.nodes[node]
    if n.op == "const":
        return float(n.data[0]), float(n.data[1])
    x = float(value[node])
    return x, x


def show(side: tuple[float, float]) -> str:
    return repr(side[0]) if side[0] == side[1] else f"[{side[0]!r}, {side[1]!r}]"
