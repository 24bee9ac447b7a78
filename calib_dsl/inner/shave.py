"""Shaving: the gap between a result's end and a value certified taken, contracted as a slice.

The inner bounds (inner/bounds.py) certify values a <= b that an unknown p takes at
solutions, inside the result [lo, hi]. Every solution with p < a lies in the slice of the box
with p in [lo, a], and that slice is contracted on its own: propagation, then fine
second-order rounds of LPs (the readings' errors as LP columns where the program has them).
Over the slice the relaxation is tighter than over the whole box (the expansion is centred
in the slice, the products with p are narrower), the other unknowns narrow, and the next
round is tighter again, where the same rounds over the whole box gain nothing (a thin
solution set in a box loose in its tails; docs/decisions/15). The slice's own lower end is
the new lo (a itself lies in the slice: a sound contraction keeps it); the upper end likewise.

Only the unknowns whose result is wider than `shave_above` times their inner interval are
shaved, at most `shave_unknowns` of them. Each end costs rounds of LPs of its own, so by
default they fit a share of the solve's time (the first always runs), and the order is the
certificate's: the next end is the wider gap of the unknown whose outer/inner ratio is the
worst *after* the ends shaved so far (one end of the loosest often brings it below the next,
whose gap the budget then reaches before the first's other end). A program
relaxed in chunks (thousands of rows) is shaved by default only where its solve ran fine
rounds: there a slice's rounds cost about what the solve's did, where a solve that ended at
its first-order fixed point says nothing of them (a slice's fine relaxation can cost many
times that solve).

An unknown still looser than `loose.above` after its ends are shaved may be loose because
another kept its whole domain (a relaxation's remainder grows with that width, over every
slice): `split.split_loose` then cuts those unknowns in halves, within `loose.share` of the
solve's time.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from calib_dsl.compile.chunks import chunked
from calib_dsl.ir.program import Program
from calib_dsl.relax.layout import independents
from calib_dsl.relax.taylor import CHUNK_SLOTS
from calib_dsl.settings import Settings
from calib_dsl.strategy.contractor import Outcome, Work
from calib_dsl.strategy.solution import Solution
from calib_dsl.strategy.split import contract_fine, split_loose


@dataclass(frozen=True)
class Shaved:
    """What shaving did: the unknowns shaved, in order, and its own clock."""

    names: tuple[str, ...]
    seconds: float
    work: Work
    halved: tuple[str, ...] = ()  # the unknowns cut in halves after (split.split_loose)


def shave(prog: Program, sol: Solution, inside_lo: np.ndarray, inside_hi: np.ndarray,
          s: Settings | None = None, budget: float | None = None, tol: float = 1e-5,
          max_sweeps: int = 1000) -> tuple[Solution, Shaved | None]:
    """`sol` with the ends of its loosest unknowns shaved towards [inside_lo, inside_hi]
    (certified inner intervals over `independents(prog)`, nan where none), and what was
    done; `sol` itself (and None) where nothing is worth shaving. With `budget` (seconds),
    an end starts only if, at the mean cost of those before, it ends within the budget (the
    first always starts, unless the budget is 0), so how many are shaved then depends on
    the machine; nor once the solve's and shaving's sweeps together reach `max_sweeps`. The
    solution's work stays the solve's: shaving's is in `Shaved`."""
    s = s or Settings()
    ind = independents(prog)
    if not candidates(sol.lo[ind], sol.hi[ind], inside_lo, inside_hi, s) or (
            budget is not None and sol.work.fine_rounds == 0
            and chunked(prog, CHUNK_SLOTS, None) is not None):
        return sol, None  # (unasked, see the module's docstring)
    start = time.perf_counter()
    lo, hi = sol.lo.copy(), sol.hi.copy()
    work = Work()
    shaved: list[tuple[int, int]] = []  # (unknown, side) in order
    while (end := worst_end(lo[ind], hi[ind], inside_lo, inside_hi, shaved, s)) is not None:
        left = max_sweeps - sol.work.sweeps - work.sweeps  # (the solve's cap holds for all)
        if left <= 0 or _over(budget, time.perf_counter() - start, len(shaved)):
            break
        k, side = end
        shaved.append(end)
        slot, value = int(ind[k]), float((inside_lo, inside_hi)[side][k])
        out = _slice(prog, (lo, hi), (slot, side, value), s, tol, left)  # from the box so far
        work = work + out.work
        # (a sound contraction of the slice keeps `value`'s solution, so its end is beyond
        # value; an empty slice would prove every solution on the other side of it)
        if side == 0:
            lo[slot] = value if out.empty else out.lo[slot]
        else:
            hi[slot] = value if out.empty else out.hi[slot]
    if not shaved:
        return sol, None
    # still loose: an unknown left its whole domain may be why (split.py's docstring)
    halved = split_loose(prog, (lo, hi), (inside_lo, inside_hi), s,
                         None if budget is None else s.loose.share * sol.seconds, tol,
                         max_sweeps - sol.work.sweeps - work.sweeps)
    lo, hi, work = halved.lo, halved.hi, work + halved.work
    names = tuple(dict.fromkeys(prog.slots.names[int(ind[k])] for k, _ in shaved))
    pieces = tuple(p for p in (_within(a, b, lo, hi) for a, b in sol.pieces) if p is not None)
    if pieces:  # every solution lies in a piece and in the shaved box: in their hull too
        lo = np.maximum(lo, np.min([p[0] for p in pieces], axis=0))
        hi = np.minimum(hi, np.max([p[1] for p in pieces], axis=0))
    if sol.history is not None:
        sol.history.record("shave", lo, hi)
    return replace(sol, lo=lo, hi=hi, pieces=pieces), Shaved(
        names, time.perf_counter() - start, work, halved.names)


def worst_end(lo: np.ndarray, hi: np.ndarray, inside_lo: np.ndarray, inside_hi: np.ndarray,
              done: list[tuple[int, int]], s: Settings) -> tuple[int, int] | None:
    """The next end to shave (unknown, side 0 low / 1 high; the arrays are over the
    unknowns): of the unknowns worth shaving in the box as it is now (`candidates`; at most
    `shave_unknowns` of them counting those in `done`), the one whose outer/inner ratio is
    the worst, its wider gap not yet shaved; None when none is left. A gap under
    shave_min_gap of the result's width is left alone."""
    begun = {k for k, _ in done}
    for k in candidates(lo, hi, inside_lo, inside_hi, replace(s, shave_unknowns=len(lo))):
        if k not in begun and len(begun) >= s.shave_unknowns:
            continue
        gaps = [(float(inside_lo[k] - lo[k]), 0), (float(hi[k] - inside_hi[k]), 1)]
        ends = [side for gap, side in sorted(gaps, reverse=True)
                if (k, side) not in done and gap > s.shave_min_gap * (hi[k] - lo[k])]
        if ends:
            return k, ends[0]
    return None


def _over(budget: float | None, spent: float, done: int) -> bool:
    """Whether the next end would overrun the budget, costing what the ones before did on
    average (the first always starts, unless the budget is 0)."""
    if budget is None:
        return False
    return budget <= 0 or (done > 0 and spent * (1 + 1 / done) > budget)


def candidates(lo: np.ndarray, hi: np.ndarray, inside_lo: np.ndarray, inside_hi: np.ndarray,
               s: Settings | None = None) -> list[int]:
    """The unknowns (indices into the arrays) worth shaving: a certified inner interval, and
    a result wider than `shave_above` times it; the loosest first, `shave_unknowns` at most."""
    s = s or Settings()
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = (hi - lo) / (inside_hi - inside_lo)
    ok = np.isfinite(inside_lo) & np.isfinite(inside_hi) & np.isfinite(lo) & np.isfinite(hi)
    ok &= (inside_lo >= lo) & (inside_hi <= hi) & (ratio > s.shave_above)
    loosest = sorted(np.flatnonzero(ok), key=lambda k: -ratio[k])
    return [int(k) for k in loosest[:s.shave_unknowns]]


def _slice(prog: Program, box: tuple[np.ndarray, np.ndarray], end: tuple[int, int, float],
           s: Settings, tol: float, max_sweeps: int) -> Outcome:
    """The slice of the box [lo, hi] beyond `value` on one side of `slot` (`end`: slot, side,
    value; side 0: [lo, value]), contracted: propagation, then fine rounds of LPs over the
    slice alone (on a working set of the rows, grown by the rows their optima violate:
    working.py)."""
    slot, side, value = end
    plo, phi = box[0].copy(), box[1].copy()
    if side == 0:
        phi[slot] = value
    else:
        plo[slot] = value
    return contract_fine(prog, plo, phi, s, tol, max_sweeps)


def _within(plo: np.ndarray, phi: np.ndarray, lo: np.ndarray,
            hi: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """A piece of a split narrowed to the shaved box (None where nothing of it is left: it
    held no solution)."""
    a, b = np.maximum(plo, lo), np.minimum(phi, hi)
    return None if np.any(a > b) else (a, b)
