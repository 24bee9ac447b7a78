"""Optional sections of a solve's report: identifiability, and a least-squares estimate."""

from __future__ import annotations

import math
import time
from typing import Any

from calib_dsl.analysis.identify import analyse, combination_enclosures
from calib_dsl.analysis.lsq import estimate
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.ir.program import Program
from calib_dsl.relax.layout import independents
from calib_dsl.settings import DEFAULT
from calib_dsl.strategy.solution import Solution


class Extras:
    """Optional sections of the report: identifiability, and a least-squares estimate."""

    def __init__(self) -> None:
        self.info: Any = None  # identify.Identifiability
        self.combinations: list[tuple[str, float, float]] = []
        self.estimate: Any = None  # lsq.Estimate
        self.seconds = 0.0
        self.skipped = ""

    def identify(self, prog: Program, res: Solution, use_lp: bool) -> None:
        start = time.perf_counter()
        if len(prog.primitives) > DEFAULT.routine_max_primitives:
            self.skipped = (f"identifiability: not analysed in solve for a program of "
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

    def not_identifiable(self) -> set[str]:
        if self.info is None:
            return set()
        return {n for members, _ in self.info.groups for n in members}

    def lsq_value(self, name: str) -> float | None:
        if self.estimate is None or name not in self.estimate.names:
            return None
        return float(self.estimate.values[self.estimate.names.index(name)])
