"""A solve's verdict: consistent, inconsistent or undecided, and never a silent fourth.

*consistent*: a parameter vector is proven to satisfy every constraint (certify_point.py: the
inner bounds' points, else the Chebyshev fit). *inconsistent*: a proof that no vector does
(the solve's, or one found here). *undecided*: neither. A solve whose point was not certified
spends a bounded effort (`verdict_share` of its own time) on a proof of inconsistency before
it says so (strategy/refute.py): a proof against each row least squares leaves
far beyond their bound (outliers/at_fault.py, where the `Effort` gives it), the fine rounds
of LPs by what each kind gains, and a split. Nothing
here narrows a result it keeps: a proof ends the solve as inconsistent, else the result is
the solve's.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from calib_dsl.analysis.certify_point import check_point
from calib_dsl.analysis.chebyshev import chebyshev, least_squares_start, with_readings
from calib_dsl.analysis.existence import prove_point
from calib_dsl.analysis.lsq import estimate
from calib_dsl.analysis.readings import Readings
from calib_dsl.inner.bounds import inner_bounds
from calib_dsl.ir.model import Model
from calib_dsl.ir.program import Program
from calib_dsl.ir.status import Consistency, Status
from calib_dsl.outliers.far import Attempts, far_rows
from calib_dsl.relax.layout import independents
from calib_dsl.settings import Settings
from calib_dsl.strategy.refute import FAILURES, Refuter, RowLoader
from calib_dsl.strategy.solution import Solution

CONSISTENT, INCONSISTENT, UNDECIDED = Consistency
EXIT_CODES = {CONSISTENT: 0, INCONSISTENT: 1, UNDECIDED: 4}  # docs/decisions/verdicts.md


@dataclass(frozen=True)
class Verdict:
    """How a solve ended, what decided it, and the effort spent beyond the solve."""

    verdict: Consistency  # CONSISTENT | INCONSISTENT | UNDECIDED
    reason: str  # one line: what proved it, or what was tried
    seconds: float = 0.0  # spent deciding (not the solve's, nor the inner bounds')
    budget: float | None = None  # what it was allowed (None: no effort was needed)
    tried: tuple[str, ...] = ()  # the attempts, a line each
    largest: float | None = None  # the Chebyshev fit's largest residual, in error bounds
    next_step: str | None = None  # the command to run next (undecided)

    @property
    def exit_code(self) -> int:
        return EXIT_CODES[self.verdict]

    def as_json(self) -> dict[str, object]:
        return {"verdict": self.verdict, "reason": self.reason, "seconds": self.seconds,
                "budget": self.budget, "tried": list(self.tried),
                "largest_residual": self.largest, "next": self.next_step}

    def headline(self) -> str:
        """The report's first line."""
        if self.verdict == UNDECIDED:
            return f"VERDICT: UNDECIDED: {self.reason}"
        return f"verdict: {self.verdict}: {self.reason}"


def least_squares(prog: Program, res: Solution, settings: Settings) -> np.ndarray | None:
    """The least-squares fit from the result's middle (None where it has no finite middle or
    the fit fails), at most settings.verdict_lsq evaluations of the residuals: where every
    solution lies, it needs few steps."""
    ind = independents(prog)
    lo, hi = res.lo[ind], res.hi[ind]
    if not np.all(np.isfinite(lo) & np.isfinite(hi)):
        return None
    try:
        with np.errstate(all="ignore"):
            values = estimate(prog, start=0.5 * (lo + hi), max_evaluations=settings.verdict_lsq,
                              sampling=settings.sampling).values
    except FAILURES:
        return None
    return values if np.all(np.isfinite(values)) else None


def certified_point(prog: Program, res: Solution | None, start: np.ndarray | None = None,
                    search: bool = False, settings: Settings | None = None
                    ) -> tuple[bool, float | None]:
    """Whether a point is proven to satisfy every constraint, and the Chebyshev fit's largest
    residual in error bounds (readings at their middles; None when there is no fit). Tried
    in order of cost: the result's middle; the Chebyshev fit in units of the rows' bounds
    from `start` (else from the least-squares estimate), then one more step of it with the
    joint readings free; with `search` (the inner bounds were not computed), their search
    for points within the result, on a program of up to inner_max_primitives. (`res` None:
    the fits alone.) The fits' steps: `settings.fits`."""
    settings = settings or Settings()
    fits = settings.fits
    ind = independents(prog)
    lo, hi = (res.lo[ind], res.hi[ind]) if res is not None else (prog.slots.lo[ind],) * 2
    need: float | None = None
    try:
        with np.errstate(all="ignore"):
            if res is not None and np.all(np.isfinite(lo) & np.isfinite(hi)) and prove_point(
                    prog, np.clip(0.5 * (lo + hi), lo, hi), Readings(prog).middles()):
                return True, None
            if len(prog.primitives):
                if start is None:
                    start = least_squares_start(prog, fits, settings.sampling)
                point, fit = chebyshev(prog, normalized=True, start=start, fits=fits)
                need = float(fit) if np.isfinite(fit) else None
                if fit <= 1.0 and check_point(prog, point).holds:
                    return True, need
                step = with_readings(prog, point, fits=fits)
                if step is not None and check_point(prog, step[0], step[1]).holds:
                    return True, need
    except FAILURES:
        pass
    if res is None or not search:
        return False, need
    try:
        return inner_bounds(prog, res.lo, res.hi, res.starts, settings).consistent, need
    except FAILURES:
        return False, need


@dataclass(frozen=True)
class Effort:
    """What a decision may load and spend: the model's data rows (to prove a row an outlier,
    the program without it: `load` must give programs on the solve's domains), the settings
    and the solve's options."""

    model: Model | None
    load: RowLoader | None
    settings: Settings = Settings()
    tol: float = 1e-5
    max_sweeps: int = 1000
    command: str = "calibc solve MODEL"  # how the user ran the solve, for the next command
    # the first attempt at a proof, against a row at fault (outliers/at_fault.py)
    at_fault: Callable[[Refuter], None] | None = None


def decide(prog: Program, res: Solution, certified: bool | None, effort: Effort | None,
           progress: Callable[[str], None] | None = None) -> tuple[Solution, Verdict]:
    """The verdict on `res` (the solve of `prog`), and the solution it ends with: `res`, or
    `res` proven empty by an effort of at most settings.verdict_share of its time.
    `certified`: whether the inner bounds certified a point (None: not computed). Without
    `effort`, no proof is sought."""
    if res.status == Status.INFEASIBLE:
        return res, Verdict(INCONSISTENT, "the solve proved that no parameter vector within "
                            "the search domains satisfies every constraint")
    if certified:
        return res, Verdict(CONSISTENT, "a parameter vector is proven to satisfy every "
                            "constraint (the inner bounds' points)")
    start = time.perf_counter()
    settings = effort.settings if effort else Settings()
    fit = least_squares(prog, res, settings)
    proven, largest = certified_point(prog, res, fit, certified is None, settings)
    if proven:
        return res, Verdict(CONSISTENT, "a parameter vector is proven to satisfy every "
                            "constraint (interval evaluation at the point)",
                            time.perf_counter() - start, largest=largest)
    if effort is None or effort.settings.verdict_share <= 0:
        far = far_rows(prog, fit, effort.settings) if fit is not None and effort else []
        return res, _undecided(prog, res, largest, (), time.perf_counter() - start, None,
                               effort, far)
    budget = effort.settings.verdict_share * res.seconds
    refuter = Refuter(prog, res, effort.model, effort.load, effort.settings, effort.tol,
                      effort.max_sweeps, budget, start, progress, at_fault=effort.at_fault)
    far = far_rows(prog, fit, effort.settings) if fit is not None and effort.model else []
    found = refuter.run(far)
    seconds = time.perf_counter() - start
    if found.proof is not None:
        emptied = replace(res, emptied=found.proof.emptied)
        return emptied, Verdict(INCONSISTENT, found.proof.text, seconds, budget,
                                tuple(found.tried), largest)
    return res, _undecided(prog, res, largest, tuple(found.tried), seconds, budget, effort,
                           found.far)


def _undecided(prog: Program, res: Solution, largest: float | None, tried: tuple[str, ...],
               seconds: float, budget: float | None, effort: Effort | None,
               far: Attempts) -> Verdict:
    fit = ("no fit" if largest is None else
           f"the Chebyshev fit's largest residual is {largest:.4g} error bounds")
    if largest is not None and largest <= 1.0:
        fit += (": within every bound in floating point, but the interval check at that "
                "point failed")
    reason = (f"no parameter vector was proven to satisfy every constraint, nor the data "
              f"proven inconsistent ({fit}); the result below encloses every solution "
              "but may be empty")
    return Verdict(UNDECIDED, reason, seconds, budget, tried, largest,
                   next_step(prog, effort, far, largest))


def next_step(prog: Program, effort: Effort | None, far: Attempts,
              largest: float | None) -> str:
    """The command to run next: with rows far beyond their bound, --outliers K (one per such
    row, at most 3); else --min-error on the const of an error bound, where the model has
    one; without an effort (hc4), the tight strategy."""
    if effort is None:  # (no effort: the quick look of --strategy hc4)
        return ("calibc solve MODEL (with the same options but the tight strategy, the "
                "default: it seeks a proof of inconsistency)")
    cmd = effort.command
    if effort.model is None or not effort.model.tables:
        return ("none with other options: the model has no data rows to leave out or bound "
                "to bracket; narrower search domains make the relaxations tighter")
    if largest is not None and largest <= 1.0 and not far:
        return ("none that decides it: the data are likely consistent (a fit within every "
                "bound), but its interval check failed (rounding at a bound, or rows that "
                "compare two computed values, as orientations, which it proves only one per "
                "configuration)")
    if far:
        return f"{cmd} --outliers {min(len(far), 3)}"
    names = _bound_consts(effort.model) if effort.model else []
    if names:
        return f"{cmd} --min-error {names[0]}"
    return f"{cmd} --outliers 1"


def _bound_consts(model: Model) -> list[str]:
    """The model's consts whose value is some column's error bound."""
    tols = [c.tol for t in model.tables for c in t.columns if c.tol > 0]
    # (a column's bound is the const's value rounded outward)
    return sorted(n for n, v in model.consts.items()
                  if any(math.isclose(float(v), tol, rel_tol=1e-9) for tol in tols))
