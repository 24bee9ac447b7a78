"""The optional sections of a solve's report, computed: identifiability, a least-squares
estimate, certified inner bounds, the result shaved towards them, and the data rows that
carry a parameter (a warning). Each fills its part of
an `Extras` (report/extras.py), which the report layer only renders."""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from calib_dsl.accuracy.points import solve_statement
from calib_dsl.analysis.identify import analyse, combination_enclosures
from calib_dsl.analysis.leverage import heavy_rows
from calib_dsl.analysis.lsq import Estimate, estimate
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.inner.bounds import inner_bounds
from calib_dsl.inner.shave import shave
from calib_dsl.ir.model import Model
from calib_dsl.ir.program import Program
from calib_dsl.ir.status import Status
from calib_dsl.outliers.rows import data_rows
from calib_dsl.relax.layout import independents
from calib_dsl.report.extras import Extras
from calib_dsl.settings import SamplingSettings, Settings
from calib_dsl.strategy.solution import Solution


def identify(extra: Extras, prog: Program, res: Solution, use_lp: bool,
             settings: Settings | None = None) -> None:
    settings = settings or Settings()
    start = time.perf_counter()
    if len(prog.primitives) > settings.routine_max_primitives:
        extra.skipped.append(f"identifiability: not analysed in solve for a program of "
                             f"{len(prog.primitives)} primitives (run `calibc identify`)")
        return
    try:
        extra.info = analyse(prog, rank_tol=settings.rank_tol)
    except CalError:  # no nominal values to linearize at: say nothing rather than guess
        return
    extra.combinations = combination_enclosures(prog, extra.info, res.lo, res.hi, use_lp,
                                                pieces=list(res.pieces),
                                                known=list(res.combinations))
    extra.seconds += time.perf_counter() - start


def least_squares(extra: Extras, prog: Program, res: Solution,
                  sampling: SamplingSettings) -> None:
    start = time.perf_counter()
    ind = independents(prog)
    mid = 0.5 * (res.lo[ind] + res.hi[ind])
    extra.estimate = estimate(prog, start=mid if all(map(math.isfinite, mid)) else None,
                              sampling=sampling)
    extra.seconds += time.perf_counter() - start


def inner(extra: Extras, prog: Program, res: Solution, asked: bool = False,
          settings: Settings | None = None) -> None:
    """Certified inner bounds, at every size; unless `asked`, not after the hc4 strategy
    (a quick look, whose loose enclosure takes the candidate points many corrections
    each: the inner bounds would cost many times its solve, docs/decisions/14)."""
    settings = settings or Settings()
    if not asked and res.strategy == "hc4":
        extra.skipped.append("inner bounds: not computed by default after --strategy hc4 "
                             "(--inner computes them)")
        return
    # the inner bounds only add to a result proven already: a numerical failure of
    # theirs is reported as such, and never costs the user the result
    try:
        extra.inner = inner_bounds(prog, res.lo, res.hi, res.starts, settings)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as err:
        extra.skipped.append(f"inner bounds: not computed ({type(err).__name__}: {err})")
        return
    extra.seconds += extra.inner.seconds


def shaved(extra: Extras, prog: Program, res: Solution, count: int | None = None,
           settings: Settings | None = None, tol: float = 1e-5,
           max_sweeps: int = 1000) -> Solution:
    """`res` with the ends of its loosest unknowns contracted towards the inner bounds
    (inner/shave.py), or `res` itself: no inner bounds, or none worth it. `count`: the
    loosest unknowns at most, whatever their ratio; if None, settings.shave_unknowns above
    settings.shave_above within a time budget of settings.shave_share of the solve's."""
    settings = settings or Settings()
    if extra.inner is None or not extra.inner.consistent or count == 0:
        if count and extra.inner is not None:
            extra.skipped.append("shaving: no certified inner bounds to shave towards")
        return res
    # (asked for a count: the loosest, whatever their ratio)
    chosen = (settings if count is None
              else replace(settings, shave_unknowns=count, shave_above=1.0))
    budget = settings.shave_share * res.seconds if count is None else None
    out, extra.shaved = shave(prog, res, extra.inner.lo, extra.inner.hi, chosen, budget, tol,
                              max_sweeps)
    return out


def leverage(extra: Extras, prog: Program, res: Solution, model: Model,
             settings: Settings) -> None:
    """The parameters whose estimate one data row carries (analysis/leverage.py), with those
    rows as the user counts them: a fault there would move the result, not show as an
    inconsistency (report/warnings.py says so). Not past settings.routine_max_primitives."""
    if (res.status == Status.INFEASIBLE or not model.tables
            or len(prog.primitives) > settings.routine_max_primitives):
        return
    heavy = heavy_rows(prog, res.lo, res.hi, settings.fits)
    extra.heavy = list(zip(heavy, data_rows(model, prog, [h.data_row for h in heavy]),
                           strict=True))


def accuracy(extra: Extras, prog: Program, res: Solution, units: tuple[str | None, frozenset[str]],
             settings: Settings, fit: Estimate | None = None) -> None:
    """The residuals before calibration (nominal point), at the least-squares point and at
    the certified centre, and the guaranteed bound over the result box (`units`: the model's
    length unit, and the measured columns read in an angle unit, left out of the distance;
    `fit`: the least-squares estimate the load made of `prog`, where the statement's starts)."""
    if not prog.slots.measured_sides:
        extra.skipped.append("accuracy: the model compares no computed value with a "
                             "measured column")
        return
    start = time.perf_counter()
    # the statement only adds to a result proven already: a numerical failure of its own is
    # reported as such, and never costs the user the result
    try:
        found = solve_statement(prog, res.lo, res.hi, extra.estimate, extra.inner, units[1],
                                settings, fit)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as err:
        extra.skipped.append(f"accuracy: not computed ({type(err).__name__}: {err})")
        return
    if not np.any(np.isfinite(found.points["nominal"])):
        extra.skipped.append("accuracy: no constraint compares a computed value with a "
                             "measured column (each measured cell became an unknown's value)")
        return
    extra.accuracy, extra.length_unit = found, units[0]
    extra.accuracy_seconds = time.perf_counter() - start
    extra.seconds += extra.accuracy_seconds
