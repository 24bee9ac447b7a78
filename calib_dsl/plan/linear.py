"""The model linearized at candidate configurations: what each one would tell about the
unknowns, before anything is measured.

The model is loaded with the candidates as its table (the measured columns, which a plan
has not got, as 0: a row's Jacobian in the unknowns does not depend on them) and every
row linearized at the planning point (the model's true values; the middle of a domain where
it states none). In units of the domains and of the bounds, row i of configuration c is

    |A[c, i] . u + noise / bound| <= 1,   u = (p - point) / (half the domain's width),

the bound being the measured side's half-width plus what the inputs' tolerances move the
row. A `lsq +- w` domain, centred on the data's estimate in a solve, is centred on the
point here.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calib_dsl.analysis.lsq import linearized
from calib_dsl.elaborate.elaborator import Inputs
from calib_dsl.elaborate.values import Values
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.ir.model import Table
from calib_dsl.ir.program import Program
from calib_dsl.pipeline import load_model
from calib_dsl.plan.configs import Configurations, table_of
from calib_dsl.relax.layout import independents

# A bound within this share of its row's value is the floats' width, not a tolerance (a row
# weighed by it would swamp the others: the design's matrices become singular).
ROUNDING = 1e-12


@dataclass(frozen=True, eq=False)
class Linear:
    """The candidates' rows: `blocks` (configurations, rows each, unknowns) in domain and
    bound units; `names`, `point`, `lo`, `hi` the unknowns, the point and their domains."""

    names: list[str]
    point: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    blocks: np.ndarray

    @property
    def half(self) -> np.ndarray:
        return 0.5 * (self.hi - self.lo)

    @property
    def box(self) -> tuple[np.ndarray, np.ndarray]:
        """The domains in u (domain units about the point)."""
        return (self.lo - self.point) / self.half, (self.hi - self.point) / self.half


def candidate_cells(t: Table, configs: Configurations) -> dict[str, np.ndarray]:
    """The table's file columns for the candidates: their inputs, the rest 0 (file units)."""
    cells = {}
    for col in t.columns:
        if col.derived:
            continue
        if col.name in configs.columns:
            cells[col.name] = configs.raw[:, configs.columns.index(col.name)]
        else:
            cells[col.name] = np.zeros(len(configs))
    return cells


def linearize(model_path: str | Path, configs: Configurations, formulation: str = "matrix",
              consts: Mapping[str, str] | None = None,
              domains: Mapping[str, tuple[float, float]] | None = None) -> Linear:
    """The candidates linearized at the planning point; `domains` (by name) replace the
    declared ones (a solve's box, when planning after measured rows)."""
    cells = candidate_cells(_table(model_path, configs, formulation, consts), configs)
    inputs = Inputs(data={configs.table: Values(cells, "<candidates>")},  # type: ignore[arg-type]
                    consts=dict(consts or {}), distinct_cells=True)
    model, prog = load_model(model_path, formulation, inputs=inputs, centre=False)
    t = table_of(model, configs.table)
    ind = independents(prog)
    names = [prog.slots.names[k] for k in ind]
    point = planning_point(prog, names, domains)
    lo, hi = _domains(prog, names, point, domains)
    lin = linearized(prog, point, owners=True)
    if not (np.all(np.isfinite(lin.jac)) and np.all(np.isfinite(lin.half))):
        raise CalError("the model's rows cannot be differentiated at the planning point (a "
                       "value or derivative undefined there)")
    tols = np.array([c.tol for c in t.columns if not c.derived])
    bound = lin.half.copy()
    if lin.dq.shape[1] == len(tols):
        bound = bound + np.abs(lin.dq) @ tols
    if np.any(bound <= 0):
        raise CalError("a measured value has no error bound (+- 0): planning weighs rows by "
                       "their bounds")
    with np.errstate(invalid="ignore", over="ignore"):
        rounding = bound <= ROUNDING * np.maximum(1.0, np.abs(lin.d))
    if np.any(rounding):
        raise CalError(f"{int(rounding.sum())} rows have no error bound at the planning point "
                       "beyond rounding: their measured side is computed from readings (as "
                       "euler_xyz(m.rx[k], ...)) whose tolerances move it by nothing there; "
                       "planning weighs rows by their bounds, so it cannot plan for them")
    rows = _by_configuration(lin.data_row, len(configs), prog)
    half = 0.5 * (hi - lo)
    scaled = lin.jac * half[None, :] / bound[:, None]
    return Linear(names, point, lo, hi, scaled[rows])


def _table(model_path: str | Path, configs: Configurations, formulation: str,
           consts: Mapping[str, str] | None) -> Table:
    from calib_dsl.elaborate.elaborator import elaborate

    first = elaborate(str(model_path), formulation=formulation, simulate_rows=1,
                      inputs=Inputs(consts=dict(consts or {})))
    return table_of(first, configs.table)


def planning_point(prog: Program, names: list[str],
                   domains: Mapping[str, tuple[float, float]] | None = None) -> np.ndarray:
    """The middle of each unknown's given domain (a solve's box: where the measured rows
    put it), else the model's true value, else the middle of its declared domain."""
    out = []
    for n in names:
        t = prog.true_values.get(n)
        if domains is not None and n in domains:
            t = 0.5 * (domains[n][0] + domains[n][1])
        if t is None:
            k = prog.slots.names.index(n)
            lo, hi = float(prog.slots.lo[k]), float(prog.slots.hi[k])
            if not (np.isfinite(lo) and np.isfinite(hi)):
                raise CalError(f"'{n}' has neither a true value nor a finite domain: planning "
                               "needs a point to linearize at (`true VALUE`)")
            t = 0.5 * (lo + hi)
        out.append(float(t))
    return np.array(out)


def _domains(prog: Program, names: list[str], point: np.ndarray,
             domains: Mapping[str, tuple[float, float]] | None
             ) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = np.empty(len(names)), np.empty(len(names))
    for i, n in enumerate(names):
        k = prog.slots.names.index(n)
        if domains is not None and n in domains:
            lo[i], hi[i] = domains[n]
        elif n in prog.priors:  # `lsq +- w`: about the point, as a solve centres it
            w = prog.priors[n][1]
            lo[i], hi[i] = point[i] - w, point[i] + w
        else:
            lo[i], hi[i] = prog.slots.lo[k], prog.slots.hi[k]
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(lo < hi)):
        bad = names[int(np.argmin(np.isfinite(lo) & np.isfinite(hi) & (lo < hi)))]
        raise CalError(f"'{bad}' has no finite search domain: planning measures widths "
                       "relative to the domains")
    return lo, hi


def _by_configuration(data_row: np.ndarray, count: int, prog: Program) -> np.ndarray:
    """(configurations, rows each): the constraint rows of each candidate, in order."""
    keys = prog.slots.row_keys or []
    config = np.array([keys[r][1] - 1 if r >= 0 else -1 for r in data_row])
    if np.any(config < 0):
        raise CalError("a row of the model depends on no configuration, or on several: "
                       "planning chooses configurations, each with rows of its own")
    order = np.argsort(config, kind="stable")
    per = np.bincount(config, minlength=count)
    if per.min() != per.max() or per.min() == 0:
        raise CalError("the candidates do not all give the same number of rows")
    return order.reshape(count, int(per[0]))
