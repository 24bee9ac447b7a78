"""The `tight` strategy: forward-backward propagation alternated with a linear relaxation of
the whole system solved by LP, to a fixed point.

Propagation contracts every temporary so the next relaxation is taken on a smaller box (its
error terms shrink quadratically with the box); the LP sees all constraints at once, which
propagation cannot. Each LP bound is certified (lpbound), so the result stays guaranteed.
"""

from __future__ import annotations

import time

import numpy as np

from .linearize import independents, relax
from .lpbound import lp_bounds
from .program import Program
from .propagate import Emptied, Result, propagate


def solve_tight(prog: Program, tol: float = 1e-5, max_sweeps: int = 1000,
                max_rounds: int = 30, min_gain: float = 1e-3) -> Result:
    """Alternate propagation and certified LP contraction until a round gains < min_gain."""
    start = time.perf_counter()
    res = propagate(prog, tol=tol, max_sweeps=max_sweeps)
    sweeps = res.sweeps
    ind = independents(prog)
    for _ in range(max_rounds):
        if res.status != "contracted":
            break
        lo, hi = res.lo, res.hi
        rel = relax(prog, lo, hi)
        if rel is None:
            break
        nlo, nhi = lp_bounds(rel, np.eye(len(ind)))
        new_lo, new_hi = np.maximum(lo[ind], nlo), np.minimum(hi[ind], nhi)
        if np.any(new_lo > new_hi):  # certified bounds cross: no solution at all
            k = int(np.flatnonzero(new_lo > new_hi)[0])
            name = prog.slots.names[int(ind[k])]
            res = Result("infeasible", lo, hi, sweeps, 0.0, "empty",
                         Emptied(name, None, "linear relaxation of all constraints"))
            break
        gain = _gain(hi[ind] - lo[ind], new_hi - new_lo)
        lo, hi = lo.copy(), hi.copy()
        lo[ind], hi[ind] = new_lo, new_hi
        res = propagate(prog, tol=tol, max_sweeps=max_sweeps, lo=lo, hi=hi)
        sweeps += res.sweeps
        if gain < min_gain:
            break
    res.sweeps = sweeps
    res.seconds = time.perf_counter() - start
    return res


def _gain(before: np.ndarray, after: np.ndarray) -> float:
    with np.errstate(invalid="ignore", divide="ignore"):
        rel = np.where(before > 0, (before - after) / before, 0.0)
    return float(np.nanmax(rel)) if len(rel) else 0.0
