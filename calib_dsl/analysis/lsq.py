"""A least-squares estimate beside the guarantee (scipy's trust-region least squares, a
Levenberg–Marquardt-type method that also respects the search domain).

Every constraint row of the program is a residual: predicted minus measured, divided by the
measurement's tolerance. The estimate is a point and a hope; `solve --lsq` prints it next to
the guaranteed enclosure and checks that it lies inside (a least-squares point can sit outside
when the data are inconsistent with their error bounds, or in a poorly identifiable direction).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calib_dsl.compile.chunks import loop_rows, spread_rows
from calib_dsl.ir.program import Program
from calib_dsl.relax.chunked import evaluation
from calib_dsl.relax.layout import independents
from calib_dsl.settings import SamplingSettings


@dataclass
class Estimate:
    names: list[str]
    values: np.ndarray
    rms: float  # root mean square of the normalized residuals (1 = at the error bound)
    worst: float  # largest normalized residual
    converged: bool
    # every row at `values` with its Jacobian, from the fit's last evaluation of all rows
    # (None: not kept); a polish from here starts without evaluating them again
    rows: Linearized | None = field(default=None, repr=False, compare=False)


def rows_at(prog: Program, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every constraint row at p (floating point): its residual (predicted minus measured),
    its bound (the half-width of its measured side), and the residual's Jacobian."""
    lin = linearized(prog, p, owners=False)
    return lin.d, lin.half, lin.jac


@dataclass(frozen=True)
class Linearized:
    """Every constraint row at a point (floating point): its residual (predicted minus
    measured), its bound (the half-width of its measured side), the residual's Jacobian in
    the unknowns, the slot it compares with, and its derivatives in the measured values of
    the one configuration it depends on (`owner`, -1 for none; one column per table column)."""

    d: np.ndarray
    half: np.ndarray
    jac: np.ndarray
    slots: np.ndarray
    dq: np.ndarray
    owner: np.ndarray
    # the residual's interval (predicted minus the measured side's whole interval): a
    # one-sided row (an inequality) has an infinite end, and d, half are then not finite
    r_lo: np.ndarray
    r_hi: np.ndarray
    # the data row (a table row id, Slots.row_keys) each row depends on: -1 none, -2 several
    data_row: np.ndarray


def linearized(prog: Program, p: np.ndarray, owners: bool = True,
               rows: np.ndarray | None = None, jacobian: bool = True) -> Linearized:
    """Every constraint row at p (of the loop's rows `rows` only, if given); `data_row`
    is -1 throughout without `owners`; without `jacobian`, `jac` has no columns (the
    residuals alone cost about half)."""
    ind = independents(prog)
    lo, hi = prog.slots.lo.copy(), prog.slots.hi.copy()
    lo[ind], hi[ind] = p, p
    ev = evaluation(prog, lo, hi, p if jacobian else p[:0], point=True, owners=owners,
                    rows=rows)
    with np.errstate(invalid="ignore", over="ignore"):  # (a point where the model is not
        done = ev.run()                                 # defined: nan rows, said by callers)
    if not done:  # every constraint was a merge of slots: nothing left to evaluate
        none = np.zeros(0)
        return Linearized(none, none, np.zeros((0, len(ind) if jacobian else 0)),
                          np.zeros(0, np.int64),
                          np.zeros((0, 0)), np.zeros(0, np.int64), none, none,
                          np.zeros(0, np.int64))

    def mid(part: int) -> np.ndarray:
        with np.errstate(invalid="ignore", over="ignore"):
            return np.concatenate([0.5 * (r[part][0] + r[part][1]) for r in done])

    half = np.concatenate([0.5 * (r[0][1] - r[0][0]) for r in done])
    d, jac, dq = mid(0), mid(1), mid(2)
    # an implied row that bounds a computed entry by a constant (ir/primitives.Slots.implied:
    # an orientation's entry the model computes as 0, its angles measured) holds wherever
    # the angle rows do; its bound is a few ulps, and a fit would weigh it beyond all others.
    # (The implied rows between two computed sides keep their residuals: they guide a fit
    # from far away, where the angles' atan2 may wrap.)
    if prog.slots.implied:  # (a fit evaluates every row many times: only where some are)
        t = ev.targets()
        capped = np.isfinite(prog.slots.lo[t]) | np.isfinite(prog.slots.hi[t])
        implied = capped & np.isin(t, np.fromiter(prog.slots.implied, dtype=np.int64))
        d[implied], jac[implied], dq[implied] = 0.0, 0.0, 0.0
    return Linearized(d, half, jac, ev.targets(), dq,
                      np.concatenate([r[3] for r in done]),
                      np.concatenate([r[0][0] for r in done]),
                      np.concatenate([r[0][1] for r in done]),
                      ev.data_rows() if owners else np.full(len(ev.targets()), -1))


def residuals(prog: Program, p: np.ndarray, rows: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray]:
    """Normalized residuals of every constraint row at p (of the loop's rows `rows` only,
    if given), and their Jacobian."""
    return evaluated(prog, p, rows)[:2]


def normalized(lin: Linearized) -> tuple[np.ndarray, np.ndarray]:
    """The rows' residuals divided by their bounds, and their Jacobian likewise."""
    with np.errstate(all="ignore"):  # an overflow is a non-finite residual: the caller's
        scale = np.maximum(lin.half, 1e-12)
        return lin.d / scale, lin.jac / scale[:, None]


def evaluated(prog: Program, p: np.ndarray, rows: np.ndarray | None = None,
              jacobian: bool = True) -> tuple[np.ndarray, np.ndarray, Linearized]:
    """`residuals` and the rows they are made of (without `jacobian`, the Jacobian has no
    columns: the residuals alone cost about half)."""
    with np.errstate(all="ignore"):  # an overflow is a non-finite residual: the caller's
        lin = linearized(prog, p, owners=False, rows=rows, jacobian=jacobian)
    return (*normalized(lin), lin)


def estimate(prog: Program, start: np.ndarray | None = None, max_evaluations: int = 30,
             sampling: SamplingSettings | None = None) -> Estimate:
    """The least-squares estimate from `start` (the middle of the domains if None). Over
    a loop compiled once of more than 2 x `lsq_min_rows` configurations (`sampling`'s), it
    is first found on an evenly spread sample of them (a tenth, from `lsq_min_rows` to
    `lsq_rows`), then polished on all (`lsq_polish` evaluations of every row): the sample
    brings it near, where the problem is nearly linear and a few evaluations of every row
    finish it, where a fit from far away would take many (docs/decisions/11).

    A fit that stops on its budget of evaluations, not on a tolerance, has not failed: it
    goes on from where it stopped, then starts again from the middle of the domains, each
    with a budget of at least `lsq_per_unknown` per unknown; the estimate is the best fit
    found, converged when one of them stopped on a tolerance."""
    s = sampling or SamplingSettings()
    ind = independents(prog)
    lo, hi = prog.slots.lo[ind], prog.slots.hi[ind]
    with np.errstate(invalid="ignore"):
        middle = np.where(np.isfinite(lo) & np.isfinite(hi), 0.5 * (lo + hi),
                          np.clip(0.0, lo, hi))
    if start is None:
        start = middle
    budget = max(max_evaluations, s.lsq_per_unknown * len(ind))
    sample = spread_rows(prog, min(s.lsq_rows, max(s.lsq_min_rows, loop_rows(prog) // 10)))
    polish = budget
    if sample is not None:
        near = _fit(prog, start, budget, sample)
        if near.converged and np.all(np.isfinite(near.values)):
            start, polish = near.values, s.lsq_polish
    best = _fit(prog, start, polish, None)
    for again in (lambda b: b.values, lambda b: middle):
        if best.converged and np.isfinite(best.rms):
            break
        nxt = _fit(prog, again(best), budget, None)
        if nxt.converged or not best.rms <= nxt.rms:
            best = nxt
    return best


def _fit(prog: Program, start: np.ndarray, max_evaluations: int,
         rows: np.ndarray | None) -> Estimate:
    from scipy.optimize import least_squares

    ind = independents(prog)
    names = [prog.slots.names[i] for i in ind]
    lo, hi = prog.slots.lo[ind], prog.slots.hi[ind]
    # the rows at the last point evaluated and at the fit's current point (the last whose
    # Jacobian scipy asked for): a rejected trial step then leaves the current point's rows,
    # and a fit that ends there (as after a rejected step) is not evaluated there again
    cache: dict[bytes, tuple[np.ndarray, np.ndarray, Linearized]] = {}
    current = [b""]

    def both(p: np.ndarray, jacobian: bool = False
             ) -> tuple[np.ndarray, np.ndarray, Linearized]:
        key = p.tobytes()
        if key not in cache:
            for old in [k for k in cache if k != current[0]]:
                del cache[old]
            cache[key] = evaluated(prog, p, rows)
        if jacobian:
            current[0] = key
        return cache[key]

    # Trust-region reflective keeps the estimate inside the search domain; the problem is
    # nearly linear near its solution, so a few Jacobian evaluations suffice. A parameter
    # whose domain is a point (-D bound=0) is fixed there: scipy wants lower < upper.
    bounds = (np.where(np.isfinite(lo), lo, -np.inf), np.where(np.isfinite(hi), hi, np.inf))
    start = np.clip(start, bounds[0], bounds[1])
    free = bounds[0] < bounds[1]

    def full(q: np.ndarray) -> np.ndarray:
        p = start.copy()
        p[free] = q
        return p

    x, success = start, True
    with np.errstate(all="ignore"):
        r0, j0, _ = both(start)
    if not (np.all(np.isfinite(r0)) and np.all(np.isfinite(j0))):
        # scipy refuses such a start: no estimate (numbers that overflow the floats)
        return Estimate(names, start, float("inf"), float("inf"), False)
    if np.any(free):
        with np.errstate(all="ignore"):  # a trial step may overflow: scipy steps back
            sol = least_squares(lambda q: both(full(q))[0], start[free],
                                jac=lambda q: both(full(q), True)[1][:, free],
                                bounds=(bounds[0][free], bounds[1][free]), method="trf",
                                x_scale="jac", max_nfev=max_evaluations)
        x, success = full(sol.x), bool(sol.success)
    r, _, lin = both(x)
    return Estimate(names, x, float(np.sqrt(np.mean(r**2))) if len(r) else 0.0,
                    float(np.max(np.abs(r))) if len(r) else 0.0, success,
                    lin if rows is None else None)
