"""The pipeline as plain function calls: the CLI runs these, and a Python user can too.

    prog = load("models/rx90_lengths.cal")          # text -> AST -> DAG -> flat program
    sol = solve(prog)                                # the tight strategy's guaranteed box
    sol.lo[prog.slots.names.index("r0")]             # ... read on the program's slots
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from calib_dsl import sections
from calib_dsl.accuracy.extremes import certified_extremes
from calib_dsl.accuracy.points import centre_witness
from calib_dsl.accuracy.predict import Calibrated, Certified, Prediction, Source, held_at, predict
from calib_dsl.accuracy.relaxations import prediction_relaxation
from calib_dsl.analysis.min_error import MinError
from calib_dsl.analysis.min_error import min_error as find_min_error
from calib_dsl.analysis.residuals import Ranges, residual_ranges
from calib_dsl.analysis.row_screen import row_screen
from calib_dsl.elaborate.elaborator import Inputs
from calib_dsl.elaborate.rows import Selection
from calib_dsl.elaborate.units import dimension
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.inner.bounds import inner_bounds
from calib_dsl.ir.model import Model
from calib_dsl.ir.program import Program
from calib_dsl.ir.status import Status
from calib_dsl.outliers.at_fault import against_rows, of_outliers
from calib_dsl.outliers.beyond_limits import beyond_limits, table_beyond_limits
from calib_dsl.outliers.conflict import Conflict, find_conflict
from calib_dsl.outliers.proof import prove_outliers
from calib_dsl.outliers.rows import Outliers, Row, data_rows, excluding
from calib_dsl.outliers.solve import solve_outliers
from calib_dsl.problem import Problem, load_model
from calib_dsl.progress import Progress, labelled
from calib_dsl.relax.layout import independents
from calib_dsl.report.as_json import result_json
from calib_dsl.report.extras import Extras
from calib_dsl.report.min_error import conflict_json, render_conflict
from calib_dsl.report.strict_json import plain
from calib_dsl.report.text import render_summary, render_table
from calib_dsl.report.verdict import render_verdict, stderr_line
from calib_dsl.report.warnings import solve_warnings
from calib_dsl.settings import DEFAULT, Settings
from calib_dsl.strategy.refute import Refuter
from calib_dsl.strategy.solution import Solution
from calib_dsl.strategy.tight import STRATEGIES, solve_hc4, solve_tight
from calib_dsl.strategy.verdict import Effort, Verdict, decide


def load(model: str | Path, formulation: str = "matrix", data: str | Path | None = None,
         inputs: Inputs | None = None) -> Program:
    """Parse, elaborate and compile a `.cal` model (with `data` replacing its first table's
    file; `inputs`: files by table, rows, const values, as on the command line)."""
    return load_model(model, formulation, data, inputs)[1]


def min_error(model: str | Path | Problem, name: str, formulation: str = "matrix",
              inputs: Inputs | None = None, strategy: str = "tight",
              progress: Progress | None = None, settings: Settings = DEFAULT) -> MinError:
    """Bracket the smallest value of the const `name` for which the data are consistent
    (`progress`: each trial solve's stages, labelled with the trial's number). `model`: its
    file, or the problem loaded already (then `formulation` and `inputs` are its own). A
    trial the solve leaves open spends settings.min_error.share of its time on a proof (the
    first, at the goal, that of every trial after it)."""
    trials = 0

    def run(prog: Program, effort: float = 0.0) -> str:
        nonlocal trials
        trials += 1
        res = solve(prog, strategy, settings=settings,
                    progress=labelled(progress, f"trial {trials}: "))
        if effort <= 0 or res.status == Status.INFEASIBLE or settings.min_error.share <= 0:
            return res.status
        # a proof of inconsistency within `effort` trials' budgets (fine rounds, a split)
        budget = effort * settings.min_error.share * res.seconds
        found = Refuter(prog, res, None, None, settings, 1e-5, 1000, budget,
                        time.perf_counter()).run([])
        return Status.INFEASIBLE if found.proof is not None else res.status

    problem = model if isinstance(model, Problem) else \
        Problem.load(model, formulation, inputs or Inputs(), settings.fits,
                     settings.sampling)
    # every trial asks about the same priors (centred anew on each trial's data, a domain
    # along a direction the data do not see moves by millimetres, and a point certified in
    # one is outside the next)
    prove = run if strategy == "tight" else None
    return find_min_error(problem.keeping_priors(), name, run, prove, settings.min_error,
                          settings.fits, settings.sampling)


def solve(prog: Program, strategy: str = "tight", tol: float = 1e-5, max_sweeps: int = 1000,
          settings: Settings = DEFAULT, progress: Progress | None = None) -> Solution:
    """A guaranteed enclosure of every solution of the program (or the proof there is none);
    `progress` is told the stages and rounds as they end (calib_dsl/progress.py)."""
    if strategy == "hc4":
        return solve_hc4(prog, tol=tol, max_sweeps=max_sweeps, progress=progress)
    if strategy != "tight":
        raise ValueError(f"unknown strategy {strategy!r} (one of {', '.join(STRATEGIES)})")
    return solve_tight(prog, tol=tol, max_sweeps=max_sweeps, settings=settings,
                       progress=progress)


def predict_at(model: str | Path | Problem, at: str | Path, formulation: str = "matrix",
               inputs: Inputs | None = None, strategy: str = "tight",
               at_rows: Selection | None = None, progress: Progress | None = None,
               settings: Settings = DEFAULT) -> tuple[Solution, Prediction | None]:
    """Calibrate on the model's data, then predict its measurements at the configurations of
    the file `at` (its rows `at_rows`) for every parameter vector consistent with the data
    (None when the data are inconsistent), with certified inner intervals: the predictions
    at the certified points of the solve's inner bounds. `model`: its file, or the problem
    loaded already (then `formulation` and `inputs` are its own); the configurations' model
    is derived from it where it allows (Problem.with_table)."""
    problem = model if isinstance(model, Problem) else \
        Problem.load(model, formulation, inputs or Inputs(), settings.fits,
                     settings.sampling)
    prog = problem.program
    held = held_at(Source(problem.path, problem.formulation, problem.inputs, problem.model,
                          problem.with_table), at, at_rows=at_rows)
    sol = solve(prog, strategy, settings=settings, progress=progress)
    if sol.status == Status.INFEASIBLE:
        return sol, None
    ind = independents(prog)
    box = {prog.slots.names[k]: (float(sol.lo[k]), float(sol.hi[k])) for k in ind}
    points, certify = certified_points(prog, sol, settings)
    # the calibration's relaxation that loses the least (accuracy/relaxations.py)
    chosen = prediction_relaxation(prog, sol.lo, sol.hi, settings)
    rel, center = chosen if chosen is not None else (None, None)
    cal = Calibrated(box, settings, rel, center, points, certify)
    faults = tuple(table_beyond_limits(problem.model, held.table))
    return sol, replace(predict(held, cal), warnings=faults)


Certify = Callable[[np.ndarray, np.ndarray], list]


def certified_points(prog: Program, sol: Solution, settings: Settings
                     ) -> tuple[tuple[Certified, ...], Certify | None]:
    """The parameter vectors (independents' order) the inner bounds certify within the
    solve's box, and a function that pulls candidates back towards their centre until they
    are certified (none where the search fails: the predictions then have no inner
    intervals)."""
    try:
        inner = inner_bounds(prog, sol.lo, sol.hi, sol.starts, settings)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError):
        return (), None
    centre = centre_witness(inner)
    if centre is None:
        return (), None
    box = (sol.lo[independents(prog)], sol.hi[independents(prog)])

    def certify(directions: np.ndarray, optima: np.ndarray) -> list[Certified]:
        # more certified points only tighten the inner intervals: a numerical failure of
        # their search (a singular or overflowing step) leaves the ones the inner bounds
        # found; a point outside the domains (ValueError) is a bug, not caught
        try:
            return certified_extremes(prog, box, centre, directions, optima, settings,
                                      row_screen(prog, *box, settings.pullback_most_open))
        except (ArithmeticError, np.linalg.LinAlgError):
            return []

    return tuple((w.point, w.readings) for w in inner.witnesses), certify


def conflict(model: str | Path | Problem, formulation: str = "matrix",
             inputs: Inputs | None = None, settings: Settings = DEFAULT) -> Conflict | None:
    """For data proven inconsistent: the worst rows without which the rest is proven
    consistent (None when the model has no table). `model`: its file, or the problem
    loaded already (then `formulation` and `inputs` are its own)."""
    problem = model if isinstance(model, Problem) else \
        Problem.load(model, formulation, inputs or Inputs(), settings.fits,
                     settings.sampling)
    return find_conflict(problem.inputs, problem.loader(), settings)


@dataclass
class SolveReport:
    """What `calibc solve` reports: the program, its solution, the optional sections, the
    rows found to conflict (inconsistent data) and the warnings."""

    prog: Program
    res: Solution
    extra: Extras
    strategy: str
    found: Conflict | None = None
    warnings: list[str] = field(default_factory=list)
    outliers: Outliers | None = None  # --outliers K: the rows at fault
    verdict: Verdict | None = None  # consistent, inconsistent or undecided
    problem: Problem | None = None  # the model as loaded for the solve (all its rows)

    def __post_init__(self) -> None:
        if self.verdict is None:  # (no decision sought: the solve's own word)
            self.verdict = decide(self.prog, self.res, None, None)[1]

    @property
    def exit_code(self) -> int:
        assert self.verdict is not None
        return self.verdict.exit_code

    def stderr_lines(self) -> list[str]:
        """What `calibc solve` prints on standard error: the warnings, and the verdict when
        it is undecided."""
        assert self.verdict is not None
        loud = stderr_line(self.verdict)
        return [f"calibc: warning: {w}" for w in self.warnings] + ([loud] if loud else [])

    def as_json(self) -> dict[str, Any]:
        """The `--json` document as plain data, in the strict JSON's convention (an infinite
        number "+oo"/"-oo", a NaN None: docs/json.md), so that any JSON writer writes it."""
        assert self.verdict is not None
        more: dict[str, Any] = {"warnings": self.warnings, "verdict": self.verdict.verdict,
                                "decision": self.verdict.as_json()}
        if self.found is not None:
            more["conflict"] = conflict_json(self.found)
        if self.outliers is not None:
            more["outliers"] = self.outliers.as_json()
        return plain({**result_json(self.prog, self.res, self.strategy, self.extra), **more})

    def text(self, every: bool = False) -> str:
        """The report `calibc solve` prints (`every`: as with --all)."""
        assert self.verdict is not None
        out = [*render_verdict(self.verdict),
               render_table(self.prog, self.res, self.extra, every, self.verdict.verdict), "",
               render_summary(self.prog, self.res, self.strategy, self.extra)]
        if self.found is not None:
            out.append(render_conflict(self.found))
        if self.outliers is not None:
            out.append(self.outliers.render())
        return "\n".join(out)


@dataclass(frozen=True)
class SolveRequest:
    """What `calibc solve` (and each `calibc batch` job) asks: the model and its inputs, the
    strategy and its limits, the report's optional sections (`inner`: True, False, or None
    for the default, on after tight; `shave`: how many of the loosest unknowns are shaved
    towards their inner bounds, settings.shave_unknowns if None; `outliers` K > 0: every
    parameter vector that satisfies all data rows but at most K), and the settings."""

    model: str | Path
    formulation: str = "matrix"
    inputs: Inputs = field(default_factory=Inputs)
    strategy: str = "tight"
    tol: float = 1e-5
    max_sweeps: int = 1000
    identify: bool = True
    lsq: bool = False
    inner: bool | None = None
    diagnose: bool = True
    outliers: int = 0
    shave: int | None = None
    settings: Settings = DEFAULT


def solve_report(request: SolveRequest, progress: Progress | None = None) -> SolveReport:
    """Load and solve the request's model, with the report's optional sections."""
    problem = Problem.load(request.model, request.formulation, request.inputs,
                           request.settings.fits, request.settings.sampling)
    if request.outliers > 0:
        run = outlier_report(request, problem, progress)
        if request.shave:
            run.extra.skipped.append("shaving: not with --outliers (it shaves towards inner "
                                     "bounds, which are not computed there)")
        return run
    return report_on(request, problem, progress)


def outlier_report(request: SolveRequest, problem: Problem,
                   progress: Progress | None = None) -> SolveReport:
    """`solve --outliers K` (outliers/solve.py). No inner bounds: they would be values
    taken by vectors that satisfy every row, not by S_K."""
    model, k, elaborated, prog = request.model, request.outliers, problem.model, problem.program
    tol, max_sweeps, settings = request.tol, request.max_sweeps, request.settings
    if not elaborated.tables:
        raise CalError(f"{model}: --outliers needs data rows, and the model has no table")
    given = problem.inputs
    first = elaborated.tables[0].name
    loader = problem.pinned_loader()  # every program below on this one's domains (S_K's)
    proofs = prove_outliers(given, loader, k, elaborated, prog, settings, progress=progress)
    proven = [Row(p.row.table, p.row.file, p.row.line, p.row.row) for p in proofs]
    if proven:  # S_K lies in S_{K - len(proven)} of the other rows
        given = excluding(given, proven, first)
        elaborated, prog = loader(given)
    left = k - len(proven)

    def without(rows: list[int]) -> Program:
        return loader(excluding(given, data_rows(elaborated, prog, rows), first))[1]

    more: list[Row] = []
    kept: Program | None = prog  # all rows but at most k: the certain outliers out
    if left == 0:
        res = solve(prog, tol=tol, max_sweeps=max_sweeps, settings=settings, progress=progress)
        certain, possible = [], []
        found_more = (find_conflict(given, loader, settings)
                      if res.status == Status.INFEASIBLE else None)
        if found_more is not None and found_more.consistent:  # S_K is empty: name why
            more = [Row(r.table, r.file, r.line, r.row) for r in found_more.rows]
    else:
        found = solve_outliers(prog, left, without, tol=tol, max_sweeps=max_sweeps,
                               settings=settings, progress=progress)
        res, certain, possible = found.solution, found.certain, found.possible
        kept = without(certain) if 0 < len(certain) <= left else prog
    extra = Extras()
    if res.status == Status.CONTRACTED and request.identify:
        sections.identify(extra, prog, res, True, settings)
    rows = Outliers(k, sorted(proven + more + data_rows(elaborated, prog, certain),
                              key=lambda r: (r.table, r.row)),
                    ([] if res.status == Status.INFEASIBLE
                     else data_rows(elaborated, prog, possible)),
                    proven=len(proven))
    return SolveReport(prog, res, extra, "tight", None,
                       solve_warnings(prog, res), rows,
                       of_outliers(res, kept, k), problem)


def report_on(request: SolveRequest, problem: Problem,
              progress: Progress | None = None) -> SolveReport:
    """`solve_report` on the request's model loaded already."""
    r, settings = request, request.settings
    prog, elaborated = problem.program, problem.model
    res = solve(prog, r.strategy, tol=r.tol, max_sweeps=r.max_sweeps, settings=settings,
                progress=progress)
    extra = Extras()
    if res.status == Status.CONTRACTED and r.inner is not False:
        sections.inner(extra, prog, res, bool(r.inner) or bool(r.shave), settings)
    effort = effort_for(r, problem) if r.strategy == "tight" else None
    res, verdict = decide(prog, res, extra.inner.consistent if extra.inner else None, effort,
                          _told(progress))
    if res.status == Status.CONTRACTED:
        if r.inner is not False:
            if r.strategy == "tight" or r.shave:  # (hc4 is propagation alone, unless asked)
                res = sections.shaved(extra, prog, res, r.shave, settings, r.tol, r.max_sweeps)
        elif r.shave:
            extra.skipped.append("shaving: not without the inner bounds it shaves towards "
                                 "(--no-inner)")
        if r.identify:
            sections.identify(extra, prog, res, r.strategy == "tight", settings)
        if r.lsq:
            sections.least_squares(extra, prog, res, settings.sampling)
        sections.accuracy(extra, prog, res, _units_of(elaborated), settings, problem.fit)
    found = None
    if res.status == Status.INFEASIBLE and r.diagnose:
        found = conflict(problem, settings=settings)
    sections.leverage(extra, prog, res, elaborated, settings)
    warnings = beyond_limits(elaborated) + solve_warnings(prog, res, extra)
    return SolveReport(prog, res, extra, r.strategy, found, warnings, verdict=verdict,
                       problem=problem)


def _units_of(elaborated: Model | None) -> tuple[str | None, frozenset[str]]:
    """The model's length unit (None: it states none) and its columns read in an angle
    unit (the accuracy's distance leaves them out)."""
    if elaborated is None:
        return None, frozenset()
    angles = frozenset(c.name for t in elaborated.tables for c in t.columns
                       if c.unit is not None and dimension(c.unit) == "angle")
    return (elaborated.units or {}).get("length"), angles


def effort_for(request: SolveRequest, problem: Problem) -> Effort:
    """What the verdict may spend (strategy/verdict.py): the program without some data rows,
    on this one's domains (a proof about other rows must hold on the same box)."""
    given, elaborated, prog = problem.inputs, problem.model, problem.program
    load = None
    if len(elaborated.tables) == 1:
        loader = problem.pinned_loader()
        first = elaborated.tables[0].name

        def load(ids: list[int]) -> Program:
            return loader(excluding(given, data_rows(elaborated, prog, ids), first))[1]

    return Effort(elaborated, load, request.settings, request.tol, request.max_sweeps,
                  f"calibc solve {request.model} (with the same options)", against_rows)


def _told(progress: Progress | None) -> Any:
    """The verdict's steps as progress stages (no width: they do not narrow the box)."""
    if progress is None:
        return None
    start = time.perf_counter()
    return lambda label: progress(label, None, time.perf_counter() - start)


def residuals(problem: Problem, prog: Program,
              sol: Solution) -> tuple[Model, Ranges, dict[str, set[int]]]:
    """The ranges of measured minus predicted over the solve's box (`sol` of `prog`) of every
    row the solve used and of those `--exclude` left out (the model read again without
    them, when some were: it shows whether they are outliers of the result); and those left
    out, by table."""
    inputs = problem.inputs
    kept = {t: Selection(sel.ranges) for t, sel in inputs.rows.items()}
    elaborated, every = problem.loader()(replace(inputs, rows=kept))
    names = {"": elaborated.tables[0].name} if elaborated.tables else {}
    left_out = {names.get(t, t): set(sel.excluded) for t, sel in inputs.rows.items()}
    box = {prog.slots.names[k]: (float(sol.lo[k]), float(sol.hi[k])) for k in independents(prog)}
    return elaborated, residual_ranges(every, box), left_out
