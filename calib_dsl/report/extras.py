"""Optional sections of a solve's report: identifiability, a least-squares estimate,
certified inner bounds, and the result shaved towards them."""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Any

import numpy as np

from calib_dsl.accuracy.points import solve_statement
from calib_dsl.accuracy.statement import Accuracy
from calib_dsl.analysis.identify import analyse, combination_enclosures
from calib_dsl.analysis.inner import Inner, inner_bounds
from calib_dsl.analysis.lsq import estimate
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.ir.program import Program
from calib_dsl.relax.layout import independents
from calib_dsl.settings import DEFAULT, Settings
from calib_dsl.strategy.shave import Shaved, shave
from calib_dsl.strategy.solution import Solution


class Extras:
    """Optional sections of the report: identifiability, a least-squares estimate, and
    certified inner bounds."""

    def __init__(self) -> None:
        self.info: Any = None  # identify.Identifiability
        self.combinations: list[tuple[str, float, float]] = []
        self.estimate: Any = None  # lsq.Estimate
        self.inner: Inner | None = None
        self.shaved: Shaved | None = None
        self.seconds = 0.0
        self.skipped: list[str] = []  # a line each: a section not computed, and why
        self.accuracy: Accuracy | None = None
        self.length_unit: str | None = None  # the model's, where it states one
        self.accuracy_seconds = 0.0

    def identify(self, prog: Program, res: Solution, use_lp: bool) -> None:
        start = time.perf_counter()
        if len(prog.primitives) > DEFAULT.routine_max_primitives:
            self.skipped.append(f"identifiability: not analysed in solve for a program of "
                                f"{len(prog.primitives)} primitives (run `calibc identify`)")
            return
        try:
            self.info = analyse(prog)
        except CalError:  # no nominal values to linearize at: say nothing rather than guess
            return
        self.combinations = combination_enclosures(prog, self.info, res.lo, res.hi, use_lp,
                                                   pieces=list(res.pieces),
                                                   known=list(res.combinations))
        self.seconds += time.perf_counter() - start

    def least_squares(self, prog: Program, res: Solution) -> None:
        start = time.perf_counter()
        ind = independents(prog)
        mid = 0.5 * (res.lo[ind] + res.hi[ind])
        self.estimate = estimate(prog, start=mid if all(map(math.isfinite, mid)) else None)
        self.seconds += time.perf_counter() - start

    def accuracy_of(self, prog: Program, res: Solution, length_unit: str | None,
                    angles: frozenset[str] = frozenset(),
                    settings: Settings = DEFAULT) -> None:
        """The residuals before calibration (nominal point), at the least-squares point and at
        the certified centre, and the guaranteed bound over the result box (`angles`: the
        measured columns read in an angle unit, left out of the distance)."""
        if not prog.slots.measured_sides:
            self.skipped.append("accuracy: the model compares no computed value with a "
                                "measured column")
            return
        start = time.perf_counter()
        # the statement only adds to a result proven already: a numerical failure of its
        # own is reported as such, and never costs the user the result
        try:
            found = solve_statement(prog, res.lo, res.hi, self.estimate, self.inner, angles,
                                    settings)
        except (ValueError, ArithmeticError, np.linalg.LinAlgError) as err:
            self.skipped.append(f"accuracy: not computed ({type(err).__name__}: {err})")
            return
        if not np.any(np.isfinite(found.points["nominal"])):
            self.skipped.append("accuracy: no constraint compares a computed value with a "
                                "measured column (each measured cell became an unknown's "
                                "value)")
            return
        self.accuracy, self.length_unit = found, length_unit
        self.accuracy_seconds = time.perf_counter() - start
        self.seconds += self.accuracy_seconds

    def inner_bounds(self, prog: Program, res: Solution, asked: bool = False) -> None:
        """Certified inner bounds, at every size; unless `asked`, not after the hc4 strategy
        (a quick look, whose loose enclosure takes the candidate points many corrections
        each: the inner bounds cost 10-15x its solve)."""
        if not asked and res.strategy == "hc4":
            self.skipped.append("inner bounds: not computed by default after --strategy hc4 "
                                "(--inner computes them)")
            return
        # the inner bounds only add to a result proven already: a numerical failure of
        # theirs is reported as such, and never costs the user the result
        try:
            self.inner = inner_bounds(prog, res.lo, res.hi, res.starts)
        except (ValueError, ArithmeticError, np.linalg.LinAlgError) as err:
            self.skipped.append(f"inner bounds: not computed ({type(err).__name__}: {err})")
            return
        self.seconds += self.inner.seconds

    def shave(self, prog: Program, res: Solution, count: int | None = None,
              tol: float = 1e-5, max_sweeps: int = 1000) -> Solution:
        """`res` with the ends of its loosest unknowns contracted towards the inner bounds
        (strategy/shave.py), or `res` itself: no inner bounds, or none worth it. `count`: the
        loosest unknowns at most, whatever their ratio; if None, settings.shave_unknowns above
        settings.shave_above within a time budget of settings.shave_share of the solve's."""
        if self.inner is None or not self.inner.consistent or count == 0:
            if count and self.inner is not None:
                self.skipped.append("shaving: no certified inner bounds to shave towards")
            return res
        # (asked for a count: the loosest, whatever their ratio)
        settings = (DEFAULT if count is None
                    else replace(DEFAULT, shave_unknowns=count, shave_above=1.0))
        budget = DEFAULT.shave_share * res.seconds if count is None else None
        shaved, self.shaved = shave(prog, res, self.inner.lo, self.inner.hi, settings, budget,
                                    tol, max_sweeps)
        return shaved

    def inner_of(self, name: str) -> tuple[float, float] | None:
        """The certified inner interval of an unknown (None: none certified, or not asked)."""
        if self.inner is None or name not in self.inner.names:
            return None
        k = self.inner.names.index(name)
        a, b = float(self.inner.lo[k]), float(self.inner.hi[k])
        return None if math.isnan(a) else (a, b)

    def not_identifiable(self) -> set[str]:
        if self.info is None:
            return set()
        return {n for members, _ in self.info.groups for n in members}

    def lsq_value(self, name: str) -> float | None:
        if self.estimate is None or name not in self.estimate.names:
            return None
        return float(self.estimate.values[self.estimate.names.index(name)])
