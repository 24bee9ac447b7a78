"""The `tight` strategy: forward-backward propagation, then a linear relaxation of the whole
system solved by LP, re-linearized on each smaller box, then propagation again.

Propagation first brings the box down to where a first-order model is accurate (the
relaxation's error terms shrink with the square of the box). The LP sees all constraints at
once, which propagation cannot: it reaches the hull of the linearized problem. The first LP
round folds each measurement error into its row (cheap); later rounds give the measured values
of each configuration LP columns of their own, so the rows of one configuration share them.
Every LP bound is certified (lpbound), so the result stays guaranteed.
"""

from __future__ import annotations

import time

import numpy as np

from .linearize import independents, relax
from .lpbound import lp_bounds
from .program import Program
from .propagate import Emptied, Result, propagate

PRELIMINARY_TOL = 1e-2  # propagation before the first relaxation: a small box, not a fixed point
MAX_CELL_COLUMNS = 3000  # beyond, measurement errors stay folded (the LP would grow too large)
STALLED = 1e-3  # an unknown that gained less than this in a round is not re-optimized


def solve_tight(prog: Program, tol: float = 1e-5, max_sweeps: int = 1000,
                max_rounds: int = 6, min_gain: float = 0.5) -> Result:
    """Propagate, then alternate certified LP contraction while a round gains >= min_gain
    (relative width of some unknown), then propagate to the fixed point.

    Once a round with per-configuration cell columns has run, another round on its box gains
    little (the first-order model is already accurate there) and its LPs are degenerate (the
    box's faces are their optima), so the default min_gain is high.
    """
    start = time.perf_counter()
    res = propagate(prog, tol=max(tol, PRELIMINARY_TOL), max_sweeps=max_sweeps)
    sweeps, rounds = res.sweeps, 0
    ind = independents(prog)
    skip = np.zeros(len(ind), dtype=bool)
    lo, hi = res.lo, res.hi
    while res.status == "contracted" and rounds < max_rounds:
        rel = relax(prog, lo, hi, cell_variables=rounds > 0, max_cell_columns=MAX_CELL_COLUMNS)
        if rel is None:
            break
        rounds += 1
        nlo, nhi = lp_bounds(rel, np.eye(len(ind)), skip=skip)
        new_lo, new_hi = np.maximum(lo[ind], nlo), np.minimum(hi[ind], nhi)
        if np.any(new_lo > new_hi):  # certified bounds cross: no solution at all
            k = int(np.flatnonzero(new_lo > new_hi)[0])
            res = _emptied(prog, res, prog.slots.names[int(ind[k])])
            break
        gains = _gains(hi[ind] - lo[ind], new_hi - new_lo)
        lo, hi = lo.copy(), hi.copy()
        lo[ind], hi[ind] = new_lo, new_hi
        skip = gains < STALLED
        if gains.max(initial=0.0) < min_gain and rounds > 1:
            break
    if res.status == "contracted":
        res = propagate(prog, tol=tol, max_sweeps=max_sweeps, lo=lo, hi=hi)
        sweeps += res.sweeps
    res.sweeps = sweeps
    res.rounds = rounds
    res.seconds = time.perf_counter() - start
    return res


def _emptied(prog: Program, res: Result, name: str) -> Result:
    return Result("infeasible", res.lo, res.hi, res.sweeps, 0.0, "empty",
                  Emptied(name, None, "the linear relaxation of all constraints together"))


def _gains(before: np.ndarray, after: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(before > 0, (before - after) / np.where(before > 0, before, 1), 0.0)
