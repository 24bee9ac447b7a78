"""Rounds of LPs on a working set of a table's rows, grown by the rows their optima violate.

An LP's bound rests on few rows (an optimum of 23 unknowns binds on at most 23), and a
campaign's configurations repeat one another: the rounds (every phase: first order, the
fine second-order rounds, the readings' rounds) run on a working set of the loop's rows,
evenly spread, to their fixed point. Then the check: each bound's optimum in the last
round's LPs (the fine rounds' where they ran), as a parameter vector, is evaluated on every
row of the campaign (a point check, with the readings at their midpoints), and so are
the fine rounds' own relaxation rows (relaxed_check.py). The rows it
violates are where the working set's LPs let through parameters the whole campaign
excludes: the worst of them join the set and the rounds run again, until no optimum
violates a row (or `working_passes` checks); a pass after a check resumes the fine
rounds. A pass that a check follows ends after its first fine round
(`fine_rounds_per_check`): another round on the same rows would only confirm that one's
fixed point, while the next pass's rounds run with the rows the check joins; where the
check joins none, the rounds go on on the same rows until their phases end. Where a
pass resumes the phase the pass before ran in, to its end, an end whose optimum no row
found cuts off gets no LP in its first round: with those rows joined, the same LP keeps
that optimum (the box it is relaxed on has moved by less than the rounds' stop ratio, so
another LP would gain little there). A working set of every row is the plain rounds on all rows,
with no check.

Every relaxation of some rows holds every solution (fewer constraints: looser, never wrong),
every bound is certified from its own LP's multipliers, and propagation runs on every row:
the working set only chooses which rows the LPs see.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from calib_dsl.analysis.certify_point import CHECK_CELLS, check_points
from calib_dsl.compile.chunks import chunked, loop_rows, start_rows
from calib_dsl.ir.program import Program
from calib_dsl.ir.status import Stop
from calib_dsl.lp.certify import Certificates
from calib_dsl.progress import Meter
from calib_dsl.relax.layout import independents
from calib_dsl.settings import Settings
from calib_dsl.strategy.contractor import Composable, Outcome, Work, handed
from calib_dsl.strategy.history import History
from calib_dsl.strategy.relaxed_check import violated_rows
from calib_dsl.strategy.rounds import LPRounds


@dataclass(frozen=True)
class WorkingRows(Composable):
    """The rounds on a working set of rows, grown by the check (a contractor). `certs`: the
    solve's certificates, given to the rounds when the set holds every row."""

    prog: Program
    settings: Settings
    certs: Certificates
    tol: float
    max_sweeps: int
    second_order: bool = True
    unsolved: np.ndarray | None = None
    progress: Meter | None = None
    history: History | None = None
    name: str = "rounds of LPs"
    max_rounds: int | None = None  # per pass (settings.rounds.max_rounds if None)
    fine_start: bool = False  # LPRounds.fine_start: a slice of a solved box (shave.py)

    def with_budget(self, sweeps: int) -> WorkingRows:
        return replace(self, max_sweeps=sweeps)

    def contract(self, lo: np.ndarray, hi: np.ndarray) -> Outcome:
        s, work = self.settings, Work()
        rows = start_rows(self.prog, s.sampling.working_rows)
        out = Outcome(lo, hi, Stop.NONE)
        del lo, hi  # (see contractor.handed)
        # a pass after a check resumes the fine rounds where the last ended (their box is
        # near its end: the first-order and wide rounds' gains are below their thresholds,
        # and would stop the rounds before the fine ones ran on the rows that joined)
        # (readings' columns and McCormick's inequalities both: the strongest fine rounds)
        resume, kind = False, "both"
        # the fine rounds' multipliers carry over the passes: a resumed pass's first LPs
        # start their row generation from the rows the last pass's optima bound on (a
        # working set grows by few rows, and the optima move little)
        fine = Certificates()
        settled: frozenset[tuple[int, float]] = frozenset()
        whole = False  # the next pass runs its fine rounds until their phases end
        for passes in range(s.sampling.working_passes + 1):
            every = rows is None or len(rows) >= loop_rows(self.prog)
            last = every or rows is None or passes == s.sampling.working_passes
            certs = self.certs if every else Certificates()
            # (a pass a check follows: one fine round, then the check's rows join)
            limit = None if last or whole else s.sampling.fine_rounds_per_check
            rounds = LPRounds(self.prog, s, certs, self.tol, self.max_sweeps - work.sweeps,
                              self.max_rounds or s.rounds.max_rounds, self.second_order,
                              unsolved=self.unsolved, progress=self.progress,
                              history=self.history, rows=None if every else rows,
                              fine_start=self.fine_start or resume,
                              fine_kind=kind if resume else "readings",
                              fine_certs=fine, settled=settled, fine_rounds=limit)
            before = work
            box = handed(out)
            del out
            out = rounds.contract(box.pop(), box.pop())
            work = work + out.work
            if last or out.empty or work.sweeps >= self.max_sweeps:
                break
            assert rows is not None  # (`last` otherwise)
            # the last LPs' optima: the fine rounds' where they ran, else the first order's
            points = fine.points if fine.points else certs.points
            found, cut = self.violated(out.lo, out.hi, points, rows)
            relaxed, relaxed_cut = self.relaxed_violated(fine, rows)
            violated = np.union1d(found, relaxed)
            if self.history is not None:
                self.history.record(f"row check on all {loop_rows(self.prog)} rows: "
                                    f"{len(violated)} rows violated by the optima of LPs on "
                                    f"{len(rows)} working rows", out.lo, out.hi)
            # a pass cut short (its fine rounds reached the limit) whose check joins no row
            # goes on with the rounds on the same rows, until their phases end: the
            # check's rows were the reason to stop early
            cut_short = limit is not None and (work - before).fine_rounds >= limit
            if len(violated) == 0 and not cut_short:
                break
            whole = len(violated) == 0
            rows = np.union1d(rows, violated)
            # a pass that resumes the phase the last one ran (the fine rounds with both,
            # after such a pass) re-solves the ends whose optima the rows found cut off;
            # every end after a pass cut short (its box moved since by a whole round's gain,
            # not less than the rounds' stop ratio)
            settled = (_settled(set(points) & set(fine.columns), cut | relaxed_cut)
                       if resume and relaxed_cut is not None and not cut_short
                       else frozenset())
            resume = bool(fine.points)
        return Outcome(out.lo, out.hi, out.stop, work, out.emptied)

    def relaxed_violated(self, fine: Certificates, rows: np.ndarray
                         ) -> tuple[np.ndarray, set[tuple[int, float]] | None]:
        """The loop rows outside `rows` whose second-order relaxation (the fine rounds' last,
        on their box) cuts off one of their LPs' optima: the `rows_added` worst, shared among
        the optima (relaxed_check.py); and the ends (keys of `fine.columns`) whose optimum
        some row cuts off (None: not checked)."""
        outside = np.setdiff1d(np.arange(loop_rows(self.prog)), rows)
        found = violated_rows(self.prog, fine, outside, self.settings.lp.workers)
        if not found:
            return np.zeros(0, dtype=np.int64), None
        cut = {end for end, (row, _) in zip(fine.columns, found, strict=True) if len(row)}
        per = max(1, self.settings.lp.rows_added // len(found))
        picked = [_first_distinct(row[np.argsort(-excess)], per) for row, excess in found]
        return np.unique(np.concatenate(picked)).astype(np.int64), cut

    def violated(self, lo: np.ndarray, hi: np.ndarray, points: dict[tuple[int, float], np.ndarray],
                 rows: np.ndarray) -> tuple[np.ndarray, set[tuple[int, float]]]:
        """The loop rows outside `rows` that some point (inside the box) violates: the
        `rows_added` worst of all, shared among the points; and the points' keys that some
        row violates. The rows are checked a chunk at a time, every point in one pass over
        a chunk (CHECK_CELLS slots x points)."""
        prog, lay = self.prog, self.prog.rows
        none = np.zeros(0, dtype=np.int64)
        keys, at = list(points), np.array(list(points.values()))
        outside = np.setdiff1d(np.arange(loop_rows(prog)), rows)
        if lay is None or len(at) == 0 or len(outside) == 0:
            return none, set()
        ind = independents(prog)
        at = np.clip(at, lo[ind], hi[ind])
        base = prog.slots.lo, prog.slots.hi
        found: list[list[tuple[np.ndarray, np.ndarray]]] = [[] for _ in at]
        for ch in chunked(prog, max(1, CHECK_CELLS // len(at)), outside) or []:
            try:
                checks = check_points(ch.prog, at, box=(ch.box(base[0]), ch.box(base[1])))
            except ValueError:  # (a point outside the domains: none to check)
                return none, set(keys)
            for k, c in enumerate(checks):
                bad = (c.excess > 0) & ch.kept(c.slots) & (c.slots >= lay.shared)
                row = (ch.slots(c.slots[bad]) - lay.shared) // max(lay.width, 1)
                found[k].append((row, c.excess[bad]))
        per = max(1, self.settings.lp.rows_added // len(at))
        picked, cut = [], set()
        for key, parts in zip(keys, found, strict=True):
            if parts:
                row, excess = (np.concatenate(x) for x in zip(*parts, strict=True))
                picked.append(_first_distinct(row[np.argsort(-excess)], per))
                if len(row):
                    cut.add(key)
        return (np.unique(np.concatenate(picked)) if picked else none), cut


def _settled(ends: set[tuple[int, float]], cut: set[tuple[int, float]]
             ) -> frozenset[tuple[int, float]]:
    """The ends whose LPs the next pass need not solve again: those whose optimum no row
    found cuts off (the rows joining the set leave it feasible, so the same LP with them
    has the same optimum)."""
    return frozenset(ends - cut)


def _first_distinct(rows: np.ndarray, count: int) -> np.ndarray:
    """The first `count` distinct values of `rows`, in their order."""
    _, first = np.unique(rows, return_index=True)
    return rows[np.sort(first)][:count]
