"""The fixed-point propagator: forward-backward sweeps over the flat program.

A sweep evaluates the groups upward (each output intersected with the enclosure of its
primitive's image) and projects them downward (each argument intersected with its optimal
projection). Everything is a numpy call per group; a slot that receives several projections in
one group intersects them all at once (`fmax.at` / `fmin.at`). fmax/fmin ignore NaN, so a NaN
could only ever mean "no contraction", never a lost solution.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from calib_dsl.ir.program import Program
from calib_dsl.ir.rows import tiled_mask
from calib_dsl.ir.status import UNKNOWNS, Status, Stop
from calib_dsl.propagate.diagnose import Emptied, sweep_from
from calib_dsl.propagate.kernels import MOVED, Share, fast_sweep, kernels


@dataclass(frozen=True)
class Result:
    """One call of the propagator: the contracted box, or where it proved there is none."""

    status: Status
    lo: np.ndarray
    hi: np.ndarray
    sweeps: int
    seconds: float
    stop: Stop  # why the loop stopped
    emptied: Emptied | None = None


def propagate(prog: Program, tol: float = 1e-5, max_sweeps: int = 1000,
              lo: np.ndarray | None = None, hi: np.ndarray | None = None,
              share: Share | None = None, own: bool = False) -> Result:
    """Contract the program's domains (or the given box) to a fixed point; a large group's
    steps shared among threads as `share` says (the same box: kernels.py). With `own`, the
    given arrays are contracted in place (the caller's copies: a large program's box is
    then held once less at the sweeps' peak), else copies of them."""
    start = time.perf_counter()
    box = [prog.slots.lo.copy() if lo is None else lo if own else lo.copy(),
           prog.slots.hi.copy() if hi is None else hi if own else hi.copy()]
    watch = _watched(prog)
    if np.any(box[0] > box[1]):
        s = int(np.flatnonzero(box[0] > box[1])[0])
        return _infeasible(box, 0, start, Emptied(prog.slots.names[s], prog.slots.origin[s], None))
    sweeps, stop = 0, Stop.MAX_SWEEPS
    steps = kernels(prog)
    # whether each slot moved in this sweep or the one before (kernels.MOVED)
    stamp = np.zeros(len(box[0]), dtype=np.uint8)
    while sweeps < max_sweeps:
        before = (box[0][watch].copy(), box[1][watch].copy())
        sweeps += 1
        at = fast_sweep(steps, box[0], box[1], stamp, sweeps, share)
        if at is not None:
            # The fast sweep stopped before the step that would empty a domain; from there
            # only the general steps spread emptiness exactly: the sweep goes on with them
            # (no copy of the box is kept for this).
            emptied = sweep_from(prog, box[0], box[1], at)
            if emptied is not None:
                return _infeasible(box, sweeps, start, emptied)
            stamp[:] = MOVED  # (cannot happen) as if everything moved
        gain = _contraction(before, (box[0][watch], box[1][watch]))
        if gain == 0.0:
            stop = Stop.FIXED_POINT
            break
        if gain < tol:
            stop = Stop.TOLERANCE
            break
    return Result(Status.CONTRACTED, box[0], box[1], sweeps, time.perf_counter() - start, stop)


def _watched(prog: Program) -> np.ndarray:
    """The slots whose contraction decides when to stop: the declared unknowns."""
    s = prog.slots
    idx = [i for i in s.declared if s.kinds[i] in UNKNOWNS]
    if not idx:
        idx = np.flatnonzero(~tiled_mask(s.kinds, ("const",))).tolist()
    return np.array(sorted(set(idx)), dtype=np.int64)


def _contraction(before: tuple, after: tuple) -> float:
    """The largest relative width reduction of one sweep (1 for a bound leaving infinity)."""
    (blo, bhi), (alo, ahi) = before, after
    if len(blo) == 0:
        return 0.0
    moved = (alo != blo) | (ahi != bhi)
    if not np.any(moved):
        return 0.0
    wb, wa = bhi - blo, ahi - alo
    left_infinity = (np.isinf(blo) & np.isfinite(alo)) | (np.isinf(bhi) & np.isfinite(ahi))
    with np.errstate(invalid="ignore", divide="ignore"):
        rel = np.where(np.isfinite(wb) & (wb > 0), (wb - wa) / wb,
                       np.where(left_infinity, 1.0, 0.0))
    return float(np.nanmax(rel))


def _infeasible(box, sweeps: int, start: float, emptied: Emptied) -> Result:
    return Result(Status.INFEASIBLE, box[0], box[1], sweeps, time.perf_counter() - start,
                  Stop.EMPTY, emptied)
