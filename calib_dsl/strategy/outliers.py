"""Solving with outliers (`calibc solve --outliers K`): a box holding every parameter vector
that satisfies all data rows but at most K (S_K, the union over the sets J of at most K data
rows of the solutions of the rest).

Propagation treats every constraint as hard, so it could remove a vector that fails a row.
Two steps contract S_K's box instead. First, sets of rows: cut the data rows into m groups
(round robin); the rows a vector of S_K fails lie in at most K of them, so it satisfies every
row of the other m - K. S_K lies in the union of the solution sets of the C(m, K) sets that
leave out K groups, and the hull of their tight solves (each with every row of its set hard:
propagation, LPs, second order) encloses it. With m = K + 1 each set is a single group; more
groups make larger sets, each solved on more rows (tighter, and more often proven empty), at
the cost of more solves: m is the largest that keeps them at MOST_SETS (K + 1 at least). On all
1495 UR10 rows with one outlier left, four sets of three quarters of the rows narrow 22 of
the 23 parameters where two halves narrowed 19. Then LPs alone, over relaxations made
from the box (relax/evaluation.py recomputes every temporary's range from the unknowns'
box), with the rows of each data row allowed to fail through the big-M columns of
strategy/dropping.py. Each round relaxes on the box the last one left (a smaller box:
smaller M, a tighter relaxation) until no unknown narrows by `gain`. Every bound is
certified (lp/), so the box holds S_K whatever the LP solver did.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from calib_dsl.analysis.outliers import classify
from calib_dsl.ir.program import Program
from calib_dsl.lp.bounds import lp_bounds
from calib_dsl.progress import Meter, Progress
from calib_dsl.propagate.diagnose import Emptied
from calib_dsl.relax.layout import independents
from calib_dsl.settings import DEFAULT, Settings
from calib_dsl.strategy.contractor import Work
from calib_dsl.strategy.dropping import dropping, relax_owned
from calib_dsl.strategy.solution import Solution
from calib_dsl.strategy.tight import solve_tight

GAIN = 0.01  # a round that narrows no unknown by 1 % of its width ends the loop
MAX_ROUNDS = 40
LP_ITERATIONS = 5000  # per objective; a stopped LP still certifies a (weaker) bound
MOST_SETS = 4  # tight solves of sets of rows at most, unless K + 1 are needed (block_box)


@dataclass(frozen=True)
class OutlierBox:
    """The box (over the program's slots: the declared unknowns contracted, the rest at
    their domains) or `empty` (proven: no vector fails at most K rows), and the LP rounds."""

    lo: np.ndarray
    hi: np.ndarray
    empty: bool
    rounds: int
    seconds: float


def block_box(prog: Program, k: int, without: Callable[[list[int]], Program],
              tol: float = 1e-5, max_sweeps: int = 1000, settings: Settings = DEFAULT,
              progress: Progress | None = None) -> tuple[np.ndarray, np.ndarray, Work] | None:
    """The hull of the tight solves of the sets of data rows that leave out k of `groups(k)`
    groups (round robin: row i in group i mod m), over `prog`'s slots (the declared unknowns
    narrowed, matched by name), or None when every set is proven inconsistent (then no
    vector fails at most k rows)."""
    ids = list(range(len(prog.slots.row_keys or [])))
    if len(ids) <= k:  # (every row may fail: no set is sure to hold)
        return prog.slots.lo.copy(), prog.slots.hi.copy(), Work()
    ind = independents(prog)
    lo, hi = np.full(len(ind), np.inf), np.full(len(ind), -np.inf)
    work = Work()
    m = groups(k)
    for out in itertools.combinations(range(m), k):
        part = without([i for i in ids if i % m in out])
        sol = solve_tight(part, tol=tol, max_sweeps=max_sweeps, settings=settings,
                          progress=progress)
        work = work + sol.work
        if sol.status == "infeasible":
            continue
        names = {part.slots.names[i]: i for i in part.slots.declared}
        for n, i in enumerate(ind):
            j = names.get(prog.slots.names[i])
            a, c = (sol.lo[j], sol.hi[j]) if j is not None else (prog.slots.lo[i],
                                                                  prog.slots.hi[i])
            lo[n], hi[n] = min(lo[n], a), max(hi[n], c)
    if np.all(lo > hi):
        return None
    out_lo, out_hi = prog.slots.lo.copy(), prog.slots.hi.copy()
    out_lo[ind] = np.maximum(out_lo[ind], lo)
    out_hi[ind] = np.minimum(out_hi[ind], hi)
    return out_lo, out_hi, work


def groups(k: int, most: int = MOST_SETS) -> int:
    """How many groups block_box cuts the rows into for k outliers: the most whose sets
    (every choice of k groups left out) number at most `most`, and at least k + 1."""
    m = k + 1
    while math.comb(m + 1, k) <= most:
        m += 1
    return m


def outlier_box(prog: Program, k: int, meter: Meter | None = None,
                max_rounds: int = MAX_ROUNDS,
                box: tuple[np.ndarray, np.ndarray] | None = None) -> OutlierBox:
    """Rounds of certified LPs over the relaxations that let at most k data rows fail, from
    `box` (the program's domains if None)."""
    start = time.perf_counter()
    ind = independents(prog)
    lo, hi = ((prog.slots.lo.copy(), prog.slots.hi.copy()) if box is None
              else (box[0].copy(), box[1].copy()))
    rounds = 0
    while rounds < max_rounds:
        made = relax_owned(prog, lo, hi)
        if made is None:  # an unbounded unknown: nothing to linearize over
            break
        lp = dropping(*made, k)
        lower, upper = lp_bounds(lp, np.eye(lp.main), iterations=LP_ITERATIONS)
        rounds += 1
        new_lo, new_hi = np.maximum(lo[ind], lower), np.minimum(hi[ind], upper)
        if np.any(new_lo > new_hi):  # certified bounds that cross: S_K is empty
            return OutlierBox(lo, hi, True, rounds, time.perf_counter() - start)
        old = hi[ind] - lo[ind]
        lo[ind], hi[ind] = new_lo, new_hi
        if meter is not None:
            meter(f"outlier LP round {rounds}", lo, hi)
        with np.errstate(invalid="ignore", divide="ignore"):
            gained = np.where(old > 0, 1.0 - (new_hi - new_lo) / old, 0.0)
        if not np.any(gained > GAIN):
            break
    return OutlierBox(lo, hi, False, rounds, time.perf_counter() - start)


@dataclass(frozen=True)
class WithOutliers:
    """A solve with at most k outliers: the Solution (its box over `prog`'s slots), and the
    data rows (ids of `Slots.row_keys`) that are certain and possible outliers of it."""

    solution: Solution
    certain: list[int]
    possible: list[int]


def solve_outliers(prog: Program, k: int, without: Callable[[list[int]], Program],
                   tol: float = 1e-5, max_sweeps: int = 1000, settings: Settings = DEFAULT,
                   progress: Progress | None = None) -> WithOutliers:
    """A box holding every vector of `prog`'s unknowns that satisfies all data rows but at
    most k (outlier_box), its certain and possible outliers (analysis/outliers.py). When
    exactly k rows are certain outliers, every such vector fails them (they fail on the
    whole box), so it satisfies all the others: the tight solve of the program `without`
    those rows encloses it too, and the box is the intersection (and no other row can be an
    outlier of any such vector: none is possible)."""
    start = time.perf_counter()
    meter = Meter(progress, independents(prog), start) if progress is not None else None
    blocks = block_box(prog, k, without, tol, max_sweeps, settings, progress)
    if blocks is None:  # every set inconsistent: no vector fails at most k rows
        empty = OutlierBox(prog.slots.lo, prog.slots.hi, True, 0, time.perf_counter() - start)
        return _none(prog, k, empty, Work(), start, [])
    if meter is not None:
        meter("sets of rows", blocks[0], blocks[1])
    box = outlier_box(prog, k, meter, box=blocks[:2])
    work = blocks[2] + Work(lp_rounds=box.rounds)
    if box.empty:
        return _none(prog, k, box, work, start, [])
    found = classify(prog, box.lo, box.hi)
    if found.hard_violated or len(found.certain) > k:
        return _none(prog, k, box, work, start, found.certain)
    if not found.certain or len(found.certain) < k:
        sol = Solution("tight", box.lo, box.hi, "outlier LPs", time.perf_counter() - start,
                       work)
        return WithOutliers(sol, found.certain, found.possible)
    rest = without(found.certain)
    inner = solve_tight(rest, tol=tol, max_sweeps=max_sweeps, settings=settings,
                        progress=progress)
    work = work + inner.work
    lo, hi = _intersect(prog, box, rest, inner)
    if inner.status == "infeasible" or np.any(lo > hi):
        return _none(prog, k, box, work, start, found.certain)
    sol = Solution("tight", lo, hi, inner.stop, time.perf_counter() - start, work,
                   split=inner.split, combinations=inner.combinations)
    return WithOutliers(sol, found.certain, [])


def _intersect(prog: Program, box: OutlierBox, rest: Program,
               inner: Solution) -> tuple[np.ndarray, np.ndarray]:
    """The outlier box with the declared unknowns narrowed to the tight solve's of `rest`
    (matched by name: `rest` is another program)."""
    lo, hi = box.lo.copy(), box.hi.copy()
    names = {rest.slots.names[i]: i for i in rest.slots.declared}
    for i in independents(prog):
        j = names.get(prog.slots.names[i])
        if j is not None:
            lo[i], hi[i] = max(lo[i], inner.lo[j]), min(hi[i], inner.hi[j])
    return lo, hi


def _none(prog: Program, k: int, box: OutlierBox, work: Work, start: float,
          certain: list[int]) -> WithOutliers:
    """Proven: no vector satisfies all data rows but at most k."""
    rows = "row" if k == 1 else "rows"
    emptied = Emptied(f"the unknowns (with at most {k} outlier {rows})", None, None)
    sol = Solution("tight", box.lo, box.hi, "empty", time.perf_counter() - start, work,
                   emptied)
    return WithOutliers(sol, certain, [])
