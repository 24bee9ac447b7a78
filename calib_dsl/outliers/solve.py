"""Solving with outliers (`calibc solve --outliers K`): a box holding every parameter vector
that satisfies all data rows but at most K (S_K, the union over the sets J of at most K data
rows of the solutions of the rest).

Propagation treats every constraint as hard, so it could remove a vector that fails a row.
Two steps contract S_K's box instead. First, sets of rows: cut the data rows into groups;
the rows a vector of S_K fails lie in at most K of them, so it satisfies every row of the
others. S_K lies in the union of the solution sets of the sets that leave out K groups, and
the hull of their tight solves (each with every row of its set hard: propagation, LPs,
second order) encloses it. The groups (`partition`): the suspects (the rows least squares
leaves worst) each alone, then the other rows in m groups; more groups make larger sets,
each solved on more rows (tighter, and more often proven empty), at the cost of more
solves. A row that no set still consistent leaves out holds on all of S_K, and a single
consistent set of K suspects proves them certain (`Blocks`). Then LPs alone, over
relaxations made from the box (relax/evaluation.py recomputes every temporary's range from
the unknowns' box), with the rows of each data row the sets left possible allowed to fail
through the big-M columns of outliers/dropping.py. Each round relaxes on the box the last
one left (a smaller box: smaller M, a tighter relaxation) until no unknown narrows by
`gain`. Every bound is certified (lp/), so the box holds S_K whatever the LP solver did.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.ir.program import Program
from calib_dsl.ir.status import Status, Stop
from calib_dsl.lp.bounds import lp_bounds
from calib_dsl.outliers.classify import classify
from calib_dsl.outliers.conflict import ranked_ids
from calib_dsl.outliers.dropping import dropping, relax_owned
from calib_dsl.progress import Meter, Progress, labelled
from calib_dsl.propagate.diagnose import Emptied
from calib_dsl.relax.layout import independents
from calib_dsl.settings import LPSettings, OutlierSettings, Settings
from calib_dsl.strategy.contractor import Composable, FixPoint, Outcome, Work
from calib_dsl.strategy.solution import Solution
from calib_dsl.strategy.tight import solve_tight

OUTLIERS = OutlierSettings()  # (the declared defaults, for callers that pass none)


@dataclass(frozen=True)
class OutlierBox:
    """The box (over the program's slots: the declared unknowns contracted, the rest at
    their domains) or `empty` (proven: no vector fails at most K rows), and the LP rounds."""

    lo: np.ndarray
    hi: np.ndarray
    empty: bool
    rounds: int
    seconds: float


@dataclass(frozen=True)
class Blocks:
    """The hull of block_box's sets not refuted (over the program's slots), and the data rows
    each of them leaves out: every vector of S_k fails only rows of one of those."""

    lo: np.ndarray
    hi: np.ndarray
    work: Work
    left_out: list[frozenset[int]]
    solved: bool = True  # False: k rows or fewer, every vector of the domains is in S_k

    def may_fail(self) -> set[int]:
        """The data rows some vector of S_k may fail: every other holds on all of S_k."""
        return set().union(*self.left_out)

    def certain(self, k: int) -> list[int]:
        """The rows every vector of S_k fails, proven by the sets alone: when only one set is
        not refuted and it leaves out k rows (k groups of one row each), a vector of S_k
        lies in a set that leaves out the groups of the rows it fails, padded with any other
        group; were those fewer than k, two paddings would give two sets not refuted."""
        one = self.solved and len(self.left_out) == 1
        return sorted(self.left_out[0]) if one and len(self.left_out[0]) == k else []


def block_box(prog: Program, k: int, without: Callable[[list[int]], Program],
              tol: float = 1e-5, max_sweeps: int = 1000, settings: Settings | None = None,
              progress: Progress | None = None, suspects: Sequence[int] = ()) -> Blocks | None:
    """The hull of the tight solves of the sets of data rows that leave out k of the groups
    (`partition`: each suspect alone, the other rows dealt into m), over `prog`'s slots (the
    declared unknowns narrowed, matched by name), or None when every set is proven
    inconsistent (then no vector fails at most k rows)."""
    settings = settings or Settings()
    ids = list(range(len(prog.slots.row_keys or [])))
    if len(ids) <= k:  # (every row may fail: no set is sure to hold)
        return Blocks(prog.slots.lo.copy(), prog.slots.hi.copy(), Work(), [frozenset(ids)],
                      solved=False)
    ind = independents(prog)
    lo, hi = np.full(len(ind), np.inf), np.full(len(ind), -np.inf)
    work = Work()
    left_out = []
    sets = list(itertools.combinations(partition(ids, k, suspects, settings.outliers), k))
    for number, out in enumerate(sets, 1):
        rows = sorted(set().union(*out))
        part = without(rows)
        label = f"set {number}/{len(sets)} of rows: "
        sol = solve_tight(part, tol=tol, max_sweeps=max_sweeps, settings=settings,
                          progress=labelled(progress, label))
        work = work + sol.work
        if sol.status == Status.INFEASIBLE:
            continue
        left_out.append(frozenset(rows))
        names = {part.slots.names[i]: i for i in part.slots.declared}
        for n, i in enumerate(ind):
            j = names.get(prog.slots.names[i])
            a, c = (sol.lo[j], sol.hi[j]) if j is not None else (prog.slots.lo[i],
                                                                  prog.slots.hi[i])
            lo[n], hi[n] = min(lo[n], a), max(hi[n], c)
    if not left_out:
        return None
    out_lo, out_hi = prog.slots.lo.copy(), prog.slots.hi.copy()
    out_lo[ind] = np.maximum(out_lo[ind], lo)
    out_hi[ind] = np.minimum(out_hi[ind], hi)
    return Blocks(out_lo, out_hi, work, left_out)


def partition(ids: list[int], k: int, suspects: Sequence[int] = (),
              o: OutlierSettings = OUTLIERS) -> list[frozenset[int]]:
    """block_box's groups of the data rows `ids` (more than k): the first suspects each a
    group of its own, as many as keep the sets (every choice of k groups) at
    `o.most_suspect_sets`, and the
    other rows dealt in groups(k) groups in a fixed shuffled order. A suspect alone makes
    the sets that leave it out solve every other row, and those that keep it hold it: with
    the rows at fault alone, only their sets stay consistent. Shuffled, because campaigns
    repeat their poses in patterns: a round-robin group (every m-th row) can hold so much of
    what the rows at fault contradict that the rest fits them (docs/decisions/16)."""
    m = groups(k, o.most_sets)
    alone = [r for r in dict.fromkeys(suspects) if r in set(ids)]
    while alone and math.comb(len(alone) + m, k) > o.most_suspect_sets:
        alone.pop()
    rest = np.array([r for r in ids if r not in set(alone)], dtype=np.int64)
    rest = rest[np.random.default_rng(o.deal_seed).permutation(len(rest))]
    pooled = [frozenset(rest[j::m].tolist()) for j in range(m)]
    return [frozenset([r]) for r in alone] + [g for g in pooled if g]


def groups(k: int, most: int = OUTLIERS.most_sets) -> int:
    """How many groups block_box cuts the rows into for k outliers: the most whose sets
    (every choice of k groups left out) number at most `most`, and at least k + 1."""
    m = k + 1
    while math.comb(m + 1, k) <= most:
        m += 1
    return m


@dataclass(frozen=True)
class OutlierRound(Composable):
    """A round of certified LPs over the relaxation that lets at most k data rows fail (of
    `may_fail` only, if given: every other is known to hold on S_k): the box narrowed, or
    proven to hold no vector of S_k; unchanged where there is nothing to linearize over (an
    unbounded unknown)."""

    prog: Program
    k: int
    lp: LPSettings
    may_fail: set[int] | None = None
    name: str = "outlier LPs"

    def contract(self, lo: np.ndarray, hi: np.ndarray) -> Outcome:
        made = relax_owned(self.prog, lo, hi)
        if made is None:
            return Outcome(lo, hi, Stop.NONE)
        rel = dropping(*made, self.k, self.may_fail)
        lower, upper = lp_bounds(rel, np.eye(rel.main), self.lp)
        ind = independents(self.prog)
        new_lo, new_hi = np.maximum(lo[ind], lower), np.minimum(hi[ind], upper)
        if np.any(new_lo > new_hi):  # certified bounds that cross: S_K is empty
            rows = "row" if self.k == 1 else "rows"
            emptied = Emptied(f"the unknowns (with at most {self.k} outlier {rows})", None,
                              None)
            return Outcome(lo, hi, Stop.EMPTY, Work(lp_rounds=1), emptied)
        lo, hi = lo.copy(), hi.copy()
        lo[ind], hi[ind] = new_lo, new_hi
        return Outcome(lo, hi, Stop.NONE, Work(lp_rounds=1))


def outlier_box(prog: Program, k: int, settings: Settings, meter: Meter | None = None,
                box: tuple[np.ndarray, np.ndarray] | None = None,
                may_fail: set[int] | None = None) -> OutlierBox:
    """Rounds of certified LPs over the relaxations that let at most k data rows fail (of
    `may_fail` only, if given), from `box` (the program's domains if None), to their fixed
    point: until no unknown narrows by settings.outliers.gain of its width."""
    start = time.perf_counter()
    lo, hi = ((prog.slots.lo.copy(), prog.slots.hi.copy()) if box is None
              else (box[0].copy(), box[1].copy()))
    o = settings.outliers
    one = OutlierRound(prog, k, replace(settings.lp, iterations=o.lp_iterations), may_fail)
    out = FixPoint(one, o.gain, o.max_rounds, progress=meter,
                   label="outlier LP round").contract(lo, hi)
    return OutlierBox(out.lo, out.hi, out.empty, out.work.lp_rounds,
                      time.perf_counter() - start)


@dataclass(frozen=True)
class WithOutliers:
    """A solve with at most k outliers: the Solution (its box over `prog`'s slots), and the
    data rows (ids of `Slots.row_keys`) that are certain and possible outliers of it."""

    solution: Solution
    certain: list[int]
    possible: list[int]


def solve_outliers(prog: Program, k: int, without: Callable[[list[int]], Program],
                   tol: float = 1e-5, max_sweeps: int = 1000, settings: Settings | None = None,
                   progress: Progress | None = None) -> WithOutliers:
    """A box holding every vector of `prog`'s unknowns that satisfies all data rows but at
    most k (outlier_box), its certain and possible outliers (outliers/classify.py). When
    exactly k rows are certain outliers, every such vector fails them (they fail on the
    whole box), so it satisfies all the others: the tight solve of the program `without`
    those rows encloses it too, and the box is the intersection (and no other row can be an
    outlier of any such vector: none is possible)."""
    settings = settings or Settings()
    start = time.perf_counter()
    meter = Meter.over(progress, independents(prog), prog.slots.lo, prog.slots.hi, start) \
        if progress is not None else None
    blocks = block_box(prog, k, without, tol, max_sweeps, settings, progress,
                       suspects(prog, k, settings))
    if blocks is None:  # every set inconsistent: no vector fails at most k rows
        empty = OutlierBox(prog.slots.lo, prog.slots.hi, True, 0, time.perf_counter() - start)
        return _none(prog, k, empty, Work(), start, [])
    if meter is not None:
        meter("sets of rows", blocks.lo, blocks.hi)
    if blocks.certain(k):  # the hull is the tight solve without them: nothing more to gain
        sol = Solution("tight", blocks.lo, blocks.hi, Stop.SETS_OF_ROWS,
                       time.perf_counter() - start, blocks.work)
        return WithOutliers(sol, blocks.certain(k), [])
    may_fail = blocks.may_fail()
    box = outlier_box(prog, k, settings, meter, box=(blocks.lo, blocks.hi), may_fail=may_fail)
    work = blocks.work + Work(lp_rounds=box.rounds)
    if box.empty:
        return _none(prog, k, box, work, start, [])
    found = classify(prog, box.lo, box.hi)
    if found.hard_violated or len(found.certain) > k:
        return _none(prog, k, box, work, start, found.certain)
    possible = [r for r in found.possible if r in may_fail]
    if not found.certain or len(found.certain) < k:
        sol = Solution("tight", box.lo, box.hi, Stop.OUTLIER_LPS, time.perf_counter() - start,
                       work)
        return WithOutliers(sol, found.certain, possible)
    rest = without(found.certain)
    inner = solve_tight(rest, tol=tol, max_sweeps=max_sweeps, settings=settings,
                        progress=progress)
    work = work + inner.work
    lo, hi = _intersect(prog, box, rest, inner)
    if inner.status == Status.INFEASIBLE or np.any(lo > hi):
        return _none(prog, k, box, work, start, found.certain)
    sol = Solution("tight", lo, hi, inner.stop, time.perf_counter() - start, work,
                   split=inner.split, combinations=inner.combinations)
    return WithOutliers(sol, found.certain, [])


def suspects(prog: Program, k: int, settings: Settings) -> list[int]:
    """The data rows (ids) whose least-squares residual exceeds o.suspect_residual bounds, the
    worst first, at most k + o.extra_suspects (`o`: settings.outliers; none when the estimate
    fails: then every group is dealt)."""
    o = settings.outliers
    try:
        ranked = ranked_ids(prog, settings.fits, settings.sampling)
    except (CalError, ValueError, ArithmeticError, np.linalg.LinAlgError):
        return []
    return [i for i, r in ranked if r > o.suspect_residual][:k + o.extra_suspects]


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
    sol = Solution("tight", box.lo, box.hi, Stop.EMPTY, time.perf_counter() - start, work,
                   emptied)
    return WithOutliers(sol, certain, [])
