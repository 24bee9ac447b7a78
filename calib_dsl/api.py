"""calibc from Python: the command line's work as plain functions with typed results.

    import calib_dsl as cal
    problem = cal.load("models/rx90_lengths.cal", defines={"known": 2e-5})
    result = cal.solve(problem)          # what `calibc solve` prints, as data
    result["r0"].result                  # (lo, hi), proven to hold every consistent r0

`load` takes what the command line's options give (data files or, here, arrays and lists;
row selections; const values) and compiles the model; `listing`, `solve`, `predict`,
`identify` and `min_error` run the same pipeline functions as `calibc compile`, `solve`,
`predict`, `identify` and `solve --min-error`. A mistake in a model or its data raises
`CalError` (its `render()` is the command line's `file:line:col: error: ...`). docs/api.md
is the guide.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np

from calib_dsl import pipeline
from calib_dsl.accuracy.predict import Prediction
from calib_dsl.analysis.min_error import MinError
from calib_dsl.compile.listing import render_listing
from calib_dsl.elaborate.elaborator import Inputs
from calib_dsl.elaborate.rows import RowRange, Selection, parse_numbers, parse_ranges
from calib_dsl.elaborate.values import Values
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.outliers.conflict import Conflict
from calib_dsl.outliers.rows import Outliers
from calib_dsl.problem import Problem
from calib_dsl.progress import Progress
from calib_dsl.report.extras import Extras
from calib_dsl.report.rows import contraction, narrowed, parameter_rows
from calib_dsl.strategy.solution import Solution
from calib_dsl.studies.advice import Advice, advise

__all__ = ["CalError", "Inconsistent", "Listing", "Parameter", "Problem", "Result",
           "identify", "listing", "load", "min_error", "predict", "solve"]

# a table: a CSV file, or its cells (columns by name, or rows of the declared columns)
Source = str | Path | Mapping[str, Sequence[float]] | Sequence[Sequence[float]] | np.ndarray
Rows = str | Sequence[int]  # "1..100:2, 200.." or row numbers (1: the first after the header)


class Inconsistent(Exception):
    """The data and the model were proven inconsistent where a result needs them not to be."""


def load(model: str | Path, data: Source | None = None, *,
         tables: Mapping[str, Source] | None = None,
         defines: Mapping[str, int | float | Fraction | str] | None = None,
         rows: Rows | Mapping[str, Rows] | None = None,
         exclude: Rows | Mapping[str, Rows] | None = None,
         formulation: str = "matrix", unroll: bool = False) -> Problem:
    """Load the `.cal` file `model`. `data` replaces its first table (a CSV path, or cells),
    `tables` any table by name; `defines` sets top-level consts (-D); `rows` and `exclude`
    select rows, of the first table or by table name (--rows, --exclude); `unroll` compiles
    each row of a loop over a table's rows on its own (--unroll)."""
    sources = {**({"": data} if data is not None else {}), **dict(tables or {})}
    inputs = Inputs({t: _source(t, s) for t, s in sources.items()},
                    _selections(rows, exclude),
                    {n: _const_text(v) for n, v in (defines or {}).items()}, unroll)
    return Problem.load(model, formulation, inputs)


def _source(table: str, source: Source) -> str | Path | Values:
    if isinstance(source, str | Path):
        return source
    return Values(source, f"<values of table {table}>" if table else "<values>")


def _selections(rows: Rows | Mapping[str, Rows] | None,
                exclude: Rows | Mapping[str, Rows] | None) -> dict[str, Selection]:
    """Selections by table ("": the first) from rows to use and rows to leave out."""
    out: dict[str, Selection] = {}
    for given, keep in ((rows, True), (exclude, False)):
        by_table = given if isinstance(given, Mapping) else {} if given is None else {"": given}
        for table, spec in by_table.items():
            old = out.get(table, Selection())
            try:
                if keep:
                    out[table] = Selection(_ranges(spec), old.excluded)
                else:
                    out[table] = Selection(old.ranges, _numbers(spec))
            except ValueError as err:
                raise CalError(f"{'rows' if keep else 'exclude'} {spec!r}: {err}") from None
    return out


def _ranges(spec: Rows) -> tuple[RowRange, ...]:
    if isinstance(spec, str):
        return parse_ranges(spec)
    return tuple(RowRange(int(k), int(k)) for k in spec)


def _numbers(spec: Rows) -> tuple[int, ...]:
    return parse_numbers(spec) if isinstance(spec, str) else tuple(int(k) for k in spec)


def _const_text(value: int | float | Fraction | str) -> str:
    """A const's value as -D takes it: a float by its shortest decimal (1.2 is 6/5, the
    number written), a Fraction exactly."""
    return repr(value) if isinstance(value, float) else str(value)


@dataclass(frozen=True)
class Listing:
    """What `calibc compile` prints (`text`) and what `--json` gives (`counts`)."""

    text: str
    counts: dict[str, Any]


def listing(problem: Problem) -> Listing:
    """The primitive-constraint listing of the compiled program (`calibc compile`; the
    name `compile` is the compiler's package, calib_dsl.compile)."""
    return Listing(render_listing(problem.program), problem.program.counts())


@dataclass(frozen=True)
class Parameter:
    """One declared unknown in a result: a row of `calibc solve`'s table."""

    name: str
    kind: str  # "param" | "var"
    domain: tuple[float, float]  # the search domain
    result: tuple[float, float] | None  # proven to hold every consistent value (None: none)
    width: float | None
    contraction: float | None  # width over the domain's (nan for an infinite domain)
    true: float | None  # the model's `true` value, when it states one
    identifiable: bool | None = None  # None: not analysed
    least_squares: float | None = None
    # values the unknown provably takes at solutions (None: none certified, or not asked)
    inner: tuple[float, float] | None = None

    @property
    def true_inside(self) -> bool | None:
        if self.true is None or self.result is None:
            return None
        return self.result[0] <= self.true <= self.result[1]


@dataclass(frozen=True)
class Result:
    """What `calibc solve` prints, as data: the fields of its --json, typed."""

    model: str
    status: str  # "contracted" | "infeasible"
    stop: str
    strategy: str
    seconds: float
    sweeps: int
    lp_rounds: int
    parameters: tuple[Parameter, ...]
    narrowed: tuple[str, ...]  # the unknowns the solve made narrower than their domain
    split: tuple[str, ...]  # the unknowns cut into pieces (the result is their hull)
    warnings: tuple[str, ...]
    # certified bounds of combinations the data see when their members are not identifiable
    combinations: tuple[tuple[str, float, float], ...]
    conflict: Conflict | None  # for inconsistent data: the priors, units or rows at fault
    outliers: Outliers | None  # with outliers=K: the rows certainly and possibly at fault
    # the solver's own result (boxes over all slots)
    solution: Solution = field(repr=False, compare=False)
    _report: pipeline.SolveReport = field(repr=False, compare=False)
    # the unknowns whose ends were shaved towards their inner bounds (inner/shave.py)
    shaved: tuple[str, ...] = ()

    def __getitem__(self, name: str) -> Parameter:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(f"no declared unknown '{name}' (the unknowns: "
                       f"{', '.join(p.name for p in self.parameters)})")

    @property
    def verdict(self) -> str:
        """"consistent" (a point is certified), "inconsistent" (proven) or "undecided"
        (strategy/verdict.py; calibc solve exits 0, 1 or 4)."""
        assert self._report.verdict is not None
        return self._report.verdict.verdict

    def text(self, every: bool = False) -> str:
        """The report `calibc solve` prints (`every`: as with --all)."""
        return self._report.text(every)

    def as_json(self) -> dict[str, Any]:
        """What `calibc solve --json` writes."""
        return self._report.as_json()


def solve(problem: Problem, strategy: str = "tight", *, tol: float = 1e-5,
          max_sweeps: int = 1000, identify: bool = True, lsq: bool = False,
          inner: bool | None = None, diagnose: bool = True, outliers: int = 0,
          shave: int | None = None, progress: Progress | None = None) -> Result:
    """Contract every unknown to an interval proven to hold all its consistent values, as
    `calibc solve` (the same options and defaults; `outliers` K as --outliers: every vector
    consistent with all data rows but at most K; `shave` N as --shave; `progress` as in
    calib_dsl/progress.py)."""
    prog = problem.program
    asked = pipeline.SolveRequest(problem.path, problem.formulation, problem.inputs, strategy,
                                  tol, max_sweeps, identify, lsq, inner, diagnose, outliers,
                                  shave)
    if outliers > 0:
        run = pipeline.outlier_report(asked, problem, progress)
    else:
        run = pipeline.report_on(asked, problem, progress)
    res, extra = run.res, run.extra
    unident = extra.not_identifiable()
    params = tuple(_parameter(r, extra, unident) for r in parameter_rows(prog, res))
    return Result(problem.path, res.status, res.stop, strategy, res.seconds, res.sweeps,
                  res.lp_rounds, params, tuple(narrowed(prog, res)), res.split,
                  tuple(run.warnings), tuple(extra.combinations), run.found, run.outliers,
                  res, run, extra.shaved.names if extra.shaved is not None else ())


def _parameter(row: dict[str, Any], extra: Extras, unident: set[str]) -> Parameter:
    result = row["result"]
    return Parameter(row["name"], row["kind"], row["domain"], result,
                     None if result is None else result[1] - result[0],
                     None if result is None else contraction(row["domain"], result),
                     row["true"], None if extra.info is None else row["name"] not in unident,
                     extra.lsq_value(row["name"]), extra.inner_of(row["name"]))


def predict(problem: Problem, at: str | Path, *, rows: Rows | None = None,
            strategy: str = "tight", progress: Progress | None = None) -> Prediction:
    """Calibrate, then boxes proven to hold the measurements at the configurations of the
    file `at` (its `rows`) for every parameter vector consistent with the data, as
    `calibc predict`. Inconsistent data raise `Inconsistent`."""
    selection = None if rows is None else Selection(_ranges(rows))
    _, found = pipeline.predict_at(problem, at, strategy=strategy, at_rows=selection,
                                   progress=progress)
    if found is None:
        raise Inconsistent("the data are inconsistent (the solve proved it): nothing to "
                           "predict")
    return found


def identify(problem: Problem) -> Advice:
    """Which parameters the measurements can determine, as `calibc identify`."""
    return advise(problem.program)


def min_error(problem: Problem, name: str, *, strategy: str = "tight",
              progress: Progress | None = None) -> MinError:
    """Bracket the smallest value of the const `name` (an error bound) for which the data
    are consistent, as `calibc solve --min-error NAME`."""
    return pipeline.min_error(problem, name, strategy=strategy, progress=progress)
