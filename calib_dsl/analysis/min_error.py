"""The smallest consistent error bound: a bracket [lo, hi] around the smallest value of a
`const` (the measurements' error bound) for which the data are consistent.

- hi is *proven feasible*: a parameter vector that satisfies every row under interval
  evaluation at that bound (certify_point.py). The vector is a Chebyshev fit (chebyshev.py)
  of the rows whose bound is the const, every other row within its own bound, and a last
  step of it with the joint readings free within their intervals.
- lo is *proven infeasible*: the tight solve at that bound finds no solution. Values between
  are tried from the top down, then by bisection, within a budget of solves; where they
  leave a bracket wider than `wide`, the caller's `prove` (a solve with a proof effort) tries
  the value `wide` below hi, then bisects below it, within `proofs` trials
  (MinErrorSettings, settings_analysis.py).

The rows whose residual at hi is within `binding` of it are the ones that set it. Every trial
is the problem with the const set (problem.py's `Problem.with_const`: the cells' bounds
changed where the const is only an error bound, else the model elaborated anew), so any model
whose measured values are stated `+- NAME` works, whatever else it contains.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from fractions import Fraction
from typing import Protocol

import numpy as np

from calib_dsl.analysis.certify_point import check_point
from calib_dsl.analysis.chebyshev import (
    chebyshev,
    least_squares_start,
    with_readings,
    within_domains,
)
from calib_dsl.analysis.lsq import rows_at
from calib_dsl.analysis.readings import Readings
from calib_dsl.elaborate.elaborator import Inputs
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.ir.model import Model
from calib_dsl.ir.program import Program
from calib_dsl.ir.status import Status
from calib_dsl.relax.chunked import evaluation
from calib_dsl.relax.layout import independents
from calib_dsl.settings import SamplingSettings
from calib_dsl.settings_analysis import FitSettings, MinErrorSettings


@dataclass(frozen=True)
class Binding:
    table: str
    file: str
    line: int  # in the data file
    row: int  # the data row number (1: the first after the header)
    residual: float


@dataclass
class MinError:
    name: str
    lo: float | None  # proven infeasible (None: no trial refuted)
    hi: float  # proven feasible, by `point`
    point: dict[str, float]
    within: float  # the binding rows' residuals are within this share of hi
    binding: list[Binding] = field(default_factory=list)
    trials: list[tuple[float, str]] = field(default_factory=list)  # (value, outcome)


Loader = Callable[[Inputs], tuple[Model, Program]]  # the model with other inputs
Solver = Callable[[Program], str]  # the status of a solve
# the status of a solve with a proof effort of `weight` trials' budgets (the caller's share)
Prover = Callable[[Program, float], str]


class Trials(Protocol):
    """What the bracket asks of a problem (problem.py's `Problem`): the model as loaded, and
    the same with consts set (`-D`)."""

    @property
    def model(self) -> Model: ...

    @property
    def program(self) -> Program: ...

    def with_const(self, **values: str) -> Trials: ...


def min_error(problem: Trials, name: str, solve: Solver, prove: Prover | None = None,
              settings: MinErrorSettings | None = None,
              fits: FitSettings | None = None,
              sampling: SamplingSettings | None = None) -> MinError:
    """The bracket (the module's docstring): its trials and budgets from `settings`, the
    Chebyshev fits' steps from `fits`, the least-squares sample from `sampling` (each its
    group's defaults where None)."""
    s = settings or MinErrorSettings()
    model, prog = problem.model, problem.program
    if name not in model.consts:
        have = ", ".join(sorted(model.consts)) or "none"
        raise CalError(f"--min-error {name}: the model has no numeric const '{name}' (its "
                       f"consts: {have})")
    e0 = float(model.consts[name])
    if not e0 > 0:
        raise CalError(f"--min-error {name}: its value is {e0}; give a positive one (-D)")
    rows = _bound_rows(prog, e0)
    up = Upper(name, problem, s, fits, sampling)
    hi, check_prog, point, readings = _upper(up, prog, rows)
    out = MinError(name, None, hi, dict(zip(_names(prog), point.tolist(), strict=True)),
                   s.binding)
    out.binding = _binding(model, check_prog, point, readings, hi, s.binding)
    del model, prog, check_prog  # (each trial derives its own)
    _lower(out, problem, solve, s)
    if prove is not None and out.lo is not None and out.hi > (1 + s.wide) * out.lo:
        raise_lower(out, problem, prove, s)
    return out


@dataclass(frozen=True)
class Upper:
    """What the upper end's search needs: the const, the problem, the settings."""

    name: str
    problem: Trials
    settings: MinErrorSettings
    fits: FitSettings | None
    sampling: SamplingSettings | None


def _upper(up: Upper, prog: Program, rows: np.ndarray
           ) -> tuple[float, Program, np.ndarray, np.ndarray | None]:
    """The smallest bound proven feasible (_fitted). The fit starts from least squares,
    which may leave a row of another bound beyond it (the const's rows weigh more); no
    raise of the const mends that row, so where no point is proven the fit starts again
    from the point with the least largest residual in bounds over every row."""
    lsq = least_squares_start(prog, up.fits or FitSettings(), up.sampling)
    try:
        return _fitted(up, prog, rows, lsq)
    except CalError:
        start, _ = chebyshev(prog, None, normalized=True, start=lsq, fits=up.fits)
        return _fitted(up, prog, rows, start)


def _fitted(up: Upper, prog: Program, rows: np.ndarray,
            start: np.ndarray) -> tuple[float, Program, np.ndarray, np.ndarray | None]:
    """The Chebyshev fit's point (from `start`: least squares, or a fit), or the fit continued
    with the joint readings free (their errors lower it further), whichever is certified at
    the smaller bound (a point the readings' step moves may break a row by more than its
    linear model said: then the plain fit's may be the smaller)."""
    point, need = chebyshev(prog, rows, start=start, fits=up.fits)
    step = with_readings(prog, point, rows, fits=up.fits)
    found: list[tuple[float, Program, np.ndarray, np.ndarray | None]] = []
    if step is not None and step[2] < need:
        try:
            found.append(_certified(up, step[0], step[2], Readings(prog).by_cell(step[1])))
        except CalError:
            pass
    if not found or found[0][0] > need:
        try:
            found.append(_certified(up, point, need))
        except CalError:
            if not found:
                raise
    return min(found, key=lambda f: f[0])


def _names(prog: Program) -> list[str]:
    return [prog.slots.names[i] for i in independents(prog)]


def _bound_rows(prog: Program, e0: float) -> np.ndarray:
    """Which constraint rows have the const as their bound: half-width e0 (to rounding)."""
    ind = independents(prog)
    lo, hi = prog.slots.lo[ind], prog.slots.hi[ind]
    _, half, _ = rows_at(prog, 0.5 * (lo + hi))
    rows = np.abs(half - e0) <= 1e-6 * e0
    if not np.any(rows):
        raise CalError("no compared measured value (the `m.c[k]` side of a row) has this "
                       "const as its bound: --min-error varies the bound of those, not of "
                       "readings a row computes with (as euler_xyz(m.rx[k], ...))")
    return rows


def _certified(up: Upper, point: np.ndarray, need: float,
               readings: dict[int, float] | None = None
               ) -> tuple[float, Program, np.ndarray, np.ndarray | None]:
    """The smallest tried bound (from `need` up) at which the point (with these joint
    readings, else their middles; kept within the domains) is proven feasible, the program
    that proved it, the point and the readings it was proven with."""
    name, tries = up.name, up.settings.certify_tries
    e = need * (1 + 1e-6) + 1e-12
    computed = False
    for _ in range(tries):
        prog = _trial(up.problem, name, e)
        # an LP's point may sit a rounding outside a domain (and domains centred on least
        # squares move with the data)
        point = np.clip(point, *within_domains(prog))
        values = None if readings is None else Readings(prog).from_cells(readings)
        check = check_point(prog, point, values)
        if check.holds:
            return e, prog, point, values
        e += float(np.max(check.excess[np.isfinite(check.excess)], initial=0.0)) + 1e-9 * e
        if not np.all(np.isfinite(check.excess)):
            computed = True
            break
    why = ("a constraint compares two computed values, which interval evaluation cannot "
           "prove" if computed else f"the fit's point still broke a row at {name} = {e:.6g} "
           f"after {tries} raises of the bound")
    raise CalError(f"--min-error {name}: no point could be proven feasible ({why})")


def _lower(out: MinError, problem: Trials, solve: Solver, s: MinErrorSettings) -> None:
    """Prove infeasible the largest value below hi that the budget (`s.max_solves`) allows."""
    refuted, open_ = None, out.hi
    for k, step in enumerate(s.steps):
        if k >= s.max_solves:
            break
        e = out.hi / step
        status = solve(_trial(problem, out.name, e))
        out.trials.append((e, status))
        if status == Status.INFEASIBLE:
            refuted = e
            break
        open_ = e
    solves = len(out.trials)
    while refuted is not None and solves < s.max_solves and open_ / refuted > 1.005:
        e = math.sqrt(refuted * open_)
        status = solve(_trial(problem, out.name, e))
        out.trials.append((e, status))
        solves += 1
        if status == Status.INFEASIBLE:
            refuted = e
        else:
            open_ = e
    out.lo = refuted


def _trial(problem: Trials, name: str, value: float) -> Program:
    """The program with the const at `value` (exactly: the float as a fraction)."""
    return problem.with_const(**{name: str(Fraction(value))}).program


def raise_lower(out: MinError, problem: Trials, prove: Prover, s: MinErrorSettings) -> None:
    """Raise the refuted lo towards the certified hi with `prove` (the values the solves
    left open may be refuted by it): first the goal itself, hi / (1 + s.wide), with the
    budget of every trial after it (s.proofs - 1: where it is proven they are not needed),
    and a proof ends the search; where it stays open, bisection below it, a trial's budget
    each."""
    assert out.lo is not None
    refuted, open_ = out.lo, out.hi
    goal = out.hi / (1 + s.wide) * (1 + s.goal_inside)
    for k in range(s.proofs):
        if open_ / refuted <= 1.005:
            break
        aim = k == 0 and goal > refuted
        e = goal if aim else math.sqrt(refuted * open_)
        status = prove(_trial(problem, out.name, e), s.proofs - 1.0 if aim else 1.0)
        out.trials.append((e, status))
        if status == Status.INFEASIBLE:
            refuted = e
            if e >= goal:
                break
        else:
            open_ = e
    out.lo = refuted


def _binding(model: Model, prog: Program, point: np.ndarray, readings: np.ndarray | None,
             hi: float, within: float) -> list[Binding]:
    """The measured rows bounded by hi whose residual at the proven point, with the joint
    readings it was proven with, is within `within` of hi (MinErrorSettings.binding)."""
    if readings is not None:
        at = Readings(prog).at
        lo, up = prog.slots.lo.copy(), prog.slots.hi.copy()
        lo[at], up[at] = readings, readings
        prog = replace(prog, slots=replace(prog.slots, lo=lo, hi=up))
    d, half, _ = rows_at(prog, point)
    r = np.abs(d)
    bounded = np.abs(half - hi) <= 1e-6 * hi
    near = np.flatnonzero(bounded & (r >= (1 - within) * hi))
    owners = row_owners(prog)
    tables = {t.name: t for t in model.tables}
    seen: dict[tuple[str, int], Binding] = {}
    for k in near[np.argsort(-r[near])]:
        key = owners[k] if k < len(owners) else None
        if key is None or key in seen or key[0] not in tables:
            continue
        t = tables[key[0]]
        if key[1] - 1 < len(t.numbers):
            seen[key] = Binding(t.name, t.path, t.lines[key[1] - 1], t.numbers[key[1] - 1],
                                float(r[k]))
    return list(seen.values())


def row_owners(prog: Program) -> list[tuple[str, int] | None]:
    """(table, model row) of each constraint row, in the order `residuals` gives them."""

    s = prog.slots
    if s.row_keys is None or s.cell_row is None:
        return []
    ind = independents(prog)
    p = 0.5 * (s.lo[ind] + s.hi[ind])
    lo, hi = s.lo.copy(), s.hi.copy()
    lo[ind], hi[ind] = p, p
    ev = evaluation(prog, lo, hi, p, point=True, owners=True)
    rows = ev.run()
    if not rows:
        return []
    owner = np.concatenate([r[3] for r in rows])
    # a row without a measured side of its own (a circle's points on one unknown radius)
    # belongs to the one data row whose cells it reads (-2: several, -1: none)
    owner = np.where(owner >= 0, owner, ev.data_rows())
    return [s.row_keys[o] if 0 <= o < len(s.row_keys) else None for o in owner.tolist()]
