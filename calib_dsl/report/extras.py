"""Optional sections of a solve's report: identifiability, a least-squares estimate,
certified inner bounds, and the result shaved towards them."""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Any

import numpy as np

from calib_dsl.analysis.accuracy import Accuracy, accuracy, nominal_point
from calib_dsl.analysis.identify import analyse, combination_enclosures
from calib_dsl.analysis.inner import Inner, inner_bounds
from calib_dsl.analysis.lsq import estimate
from calib_dsl.analysis.residuals import residual_ranges
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.ir.program import Program
from calib_dsl.relax.layout import independents
from calib_dsl.settings import DEFAULT
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
                    angles: frozenset[str] = frozenset()) -> None:
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
            found = _accuracy(prog, res, self.estimate, self.inner, angles)
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


def _accuracy(prog: Program, res: Solution, lsq: Any, inner: Inner | None,
              angles: frozenset[str]) -> Accuracy:
    """The accuracy at the nominal point, the least-squares point (`lsq`, an Estimate, or
    computed here: the table's column only when asked) and the certified centre."""
    ind = independents(prog)
    points = {"nominal": nominal_point(prog)}
    centre = certified_centre(inner)
    if lsq is None:  # from the certified centre, near a fit (else the box's middle)
        mid = 0.5 * (res.lo[ind] + res.hi[ind])
        start = centre if centre is not None else mid if all(map(math.isfinite, mid)) else None
        lsq = estimate(prog, start=start)
    if np.all(np.isfinite(lsq.values)):
        points["least_squares"] = lsq.values
    if centre is not None:
        points["certified"] = centre
    box = {prog.slots.names[k]: (float(res.lo[k]), float(res.hi[k])) for k in ind}
    return accuracy(prog, residual_ranges(prog, box), points, angles)


def certified_centre(inner: Inner | None) -> np.ndarray | None:
    """The certified point the inner bounds' search pulled the others towards; where the
    search needed none (its first points were certified), the certified point nearest the
    middle of the inner intervals, each unknown scaled by its inner width."""
    if inner is None or not inner.witnesses:
        return None
    if inner.centre is not None:
        return inner.centre.point
    mid = 0.5 * (inner.lo + inner.hi)
    scale = np.where(inner.hi > inner.lo, inner.hi - inner.lo, 1.0)
    gaps = [float(np.nansum(((w.point - mid) / scale) ** 2)) for w in inner.witnesses]
    return inner.witnesses[int(np.argmin(gaps))].point
