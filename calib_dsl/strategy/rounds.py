"""Rounds of certified LPs over relaxations of the whole program, each followed by propagation.

Each round re-linearizes on the box the previous one left: far from the fixed point the
model is coarse, and a round gains only part of the way, so rounds repeat while they pay.
A round is four named steps:

1. `relaxation`: second order while the box is too wide for first order (curvature above
   `wide`), else first order, with the measurement errors folded into each row (a small LP)
   or, near the end, as LP columns of their own (the hull of the linearized problem). When
   the first-order rounds are over but their remainder is still a large share of the rows'
   widths (`remainder_wide`: error bounds tighter than the model is linear over the box),
   fine second-order rounds follow: every product kept, each tied to its factors by
   McCormick's inequalities. Where that share is smaller but not negligible
   (`remainder_readings`) and the model reads measured values, the fine rounds keep the
   readings' errors as LP columns instead (relax/quadratic_readings.py). When McCormick's
   fine rounds stall while the rows' remainders still cost the bounds much (what their LPs'
   multipliers pay for them: `readings_cost`), rounds with both follow. Where the readings'
   rounds cannot help (no relaxation with them can be built, or their first round gains
   less than `fine_min_gain`: exact readings, `: +- 0`, give columns fixed at 0),
   McCormick's rounds follow, kept while they gain as much.
2. `bounds`: certified bounds on every unknown, from the last LPs' multipliers on the new
   box (a matrix product) while that pays, else from LPs solved again.
3. `narrow`: intersect the box with them (crossing bounds prove there is no solution), and
   propagate.
4. `next_round`: what the gains say about the next round (its phase: phases.py's
   `next_phase`; who sits it out), or that the rounds are over.

The rounds repeat as a `FixPoint` of one round (contractor.py): until a round says the
rounds are over (`Outcome.final`), or the rounds of LPs or sweeps they were given are spent.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from calib_dsl.ir.program import Program
from calib_dsl.ir.status import Status, Stop
from calib_dsl.lp.bounds import lp_bounds
from calib_dsl.lp.certify import Certificates, reused_bounds
from calib_dsl.progress import Meter
from calib_dsl.propagate.diagnose import Emptied
from calib_dsl.propagate.fixpoint import propagate
from calib_dsl.relax.chunked import release_freed
from calib_dsl.relax.layout import independents, measured_cells
from calib_dsl.relax.linearize import relax
from calib_dsl.relax.quadratic import FAMILY, narrowed, relax_quadratic, to_box
from calib_dsl.relax.quadratic_readings import FAMILY as READINGS_FAMILY
from calib_dsl.relax.quadratic_readings import relax_quadratic_readings
from calib_dsl.relax.relaxation import LinearRelaxation
from calib_dsl.relax.taylor import Expansion
from calib_dsl.settings import LPSettings, Settings
from calib_dsl.strategy.contractor import Composable, FixPoint, Outcome, Work, sweep_share
from calib_dsl.strategy.history import History
from calib_dsl.strategy.phases import FINE_KINDS, Measures, Phase, next_phase

SECOND_ORDER = FAMILY  # LinearRelaxation.family of quadratic.relax_quadratic's


@dataclass(frozen=True)
class LPRounds(Composable):
    """The rounds of LPs from a box (a contractor). `certs` holds the multipliers and bases
    of the LPs solved (updated in place: a split's pieces start from the whole box's). With
    `cells` the rounds start with the errors as LP columns (a box near its end); the slots
    `unsolved` get no LPs (a member left free by the change of unknowns: the data do not see
    it, and propagation gives it what its combination allows). With `history`, the box after
    each round is recorded there."""

    prog: Program
    settings: Settings
    certs: Certificates
    tol: float
    max_sweeps: int
    max_rounds: int
    second_order: bool = True
    cells: bool = False
    threads: int | None = None  # LP threads (settings.lp.workers unless given)
    unsolved: np.ndarray | None = None
    history: History | None = None
    # the loop's rows whose constraints the relaxations take (all if None): a working set
    # of many rows relaxes fast (working.py), and every relaxation of some rows is valid
    rows: np.ndarray | None = None
    name: str = "rounds of LPs"
    progress: Meter | None = None  # told the box after each round
    # straight to the fine second-order rounds, the readings' errors as LP columns where the
    # program has them (else every product tied by McCormick's inequalities): a slice of a
    # solved box (inner/shave.py) is already where first order has nothing left to give
    fine_start: bool = False
    # with fine_start, which fine rounds begin: "readings" (the readings' errors as LP
    # columns, McCormick's instead where the program has none), "mccormick" (every product
    # tied by McCormick's inequalities), or "both"
    fine_kind: str = "readings"
    # where the fine rounds keep their multipliers and optima (their own if None)
    fine_certs: Certificates | None = None
    # ends (unknown, +1 its max or -1 its min) whose optimum in the last fine LPs (kept in
    # `fine_certs`, of the phase these rounds resume) no row added since cuts off: the
    # first round solves no LP for them (with the rows added, the same LP on the box it
    # had keeps that optimum): their ends take the box's bound, tightened by those LPs'
    # multipliers certified again on this round's relaxation
    settled: frozenset[tuple[int, float]] = frozenset()
    # the fine rounds of LPs at most (None: until their phases end): a working set's pass
    # that a check follows (working.py) ends after its first, and the rounds go on in the
    # next pass with the rows the check joins
    fine_rounds: int | None = None

    def contract(self, lo: np.ndarray, hi: np.ndarray) -> Outcome:
        rounds = FixPoint(_Rounds(self, lo, hi), ratio=None, most=None, name=self.name)
        box = [hi, lo]
        del lo, hi  # (see contractor.handed)
        return rounds.contract(box.pop(), box.pop())

    def with_budget(self, sweeps: int) -> LPRounds:
        return replace(self, max_sweeps=sweeps)


@dataclass
class _Round:
    """One round's relaxation: the first-order one (None when not built), the second-order
    one with its expansion (None on a box narrow enough for first order), and whether its
    bounds come from LPs solved again (`fresh`) or from the last ones' multipliers."""

    first: LinearRelaxation | None
    quad: tuple[LinearRelaxation, Expansion] | None
    fresh: bool

    @property
    def target(self) -> LinearRelaxation:
        target = self.quad[0] if self.quad is not None else self.first
        assert target is not None
        return target


@dataclass
class _Rounds(Composable):
    """One round (a contractor, applied again by LPRounds' FixPoint from the box it left),
    and the state the rounds carry from one to the next."""

    spec: LPRounds
    lo: np.ndarray
    hi: np.ndarray
    ind: np.ndarray = field(init=False)
    phase: Phase = Phase.FOLDED
    tried: set[Phase] = field(default_factory=set)  # the phases begun
    skip: np.ndarray = field(init=False)  # unknowns that sit out the next round's LPs
    never: np.ndarray = field(init=False)  # unknowns that get no LPs at all
    moved: np.ndarray = field(init=False)  # whether any round narrowed it by `stalled`
    cellular: bool = field(init=False)  # whether cell rounds may give errors LP columns
    reuse: bool = field(init=False)  # whether the next round tries the last multipliers
    reused_in_a_row: int = 0
    last: _Round | None = None  # the last round that narrowed the box
    kind_rounds: int = 0  # rounds of LPs in the present phase
    # the fine rounds' multipliers, kept apart: the shared `certs` keep the first-order
    # rounds' bases, which the pieces of a split (first-order rounds) start from
    fine_certs: Certificates = field(default_factory=Certificates)
    work: Work = Work()
    stop: Stop = Stop.NONE
    emptied: Emptied | None = None

    def __post_init__(self) -> None:
        spec = self.spec
        self.ind = independents(spec.prog)
        self.phase = Phase.CELLS if spec.cells else Phase.FOLDED
        self.skip = np.zeros(len(self.ind), dtype=bool)
        self.never = (np.isin(self.ind, spec.unsolved) if spec.unsolved is not None
                      else self.skip.copy())
        self.moved = np.zeros(len(self.ind), dtype=bool)
        self.cellular = measured_cells(spec.prog) <= spec.settings.rounds.max_cell_columns
        self.reuse = bool(spec.certs.y)  # a piece of a split box: its whole box's multipliers
        if spec.fine_certs is not None:
            self.fine_certs = spec.fine_certs
        if spec.fine_start:
            self.phase, self.reuse = FINE_KINDS[spec.fine_kind], False
        self.tried.add(self.phase)

    @property
    def name(self) -> str:
        return "a round of LPs"

    def contract(self, lo: np.ndarray, hi: np.ndarray) -> Outcome:
        """One round from the box the last one left (`lo`, `hi` are it): the work it did,
        and `final` once the rounds are over."""
        self.lo, self.hi, before = lo, hi, self.work
        more = self.one_round()
        return Outcome(self.lo, self.hi, self.stop, self.work - before, self.emptied,
                       final=not more)

    def one_round(self) -> bool:
        """Run a round unless the rounds or sweeps given are spent; whether more follow."""
        if self.emptied is not None or self.work.lp_rounds >= self.spec.max_rounds:
            return False
        if self.work.sweeps >= self.spec.max_sweeps:  # the sweeps it was given are spent
            self.stop = Stop.MAX_SWEEPS
            return False
        # (the last round's freed relaxation and sweeps back to the system: held in the
        # chunk threads' arenas, they add to what this round's threads allocate elsewhere)
        release_freed()
        this = self.relaxation()
        if this is None:
            return False
        gains = self.narrow(self.bounds(this), this)
        if gains is None:
            return False
        self.record(this)
        more = self.next_round(this, gains)
        if self.spec.progress is not None:
            done = self.work.lp_rounds + self.work.reused_rounds
            self.spec.progress(f"LP round {done}", self.lo, self.hi)
        return more and self.emptied is None

    # -- 1. the relaxation -------------------------------------------------------------------
    def relaxation(self) -> _Round | None:
        """This round's relaxation, or None when none can be built."""
        s, prog, certs = self.spec.settings, self.spec.prog, self.spec.certs
        self.reuse = self.reuse and self.reused_in_a_row < s.rounds.reuse_rounds
        if self.phase.fine:
            fine = self._fine_relaxation()
            if fine is None:  # (beyond the models' memory bound, or no readings to keep)
                return None
            return _Round(None, fine, True)  # (their multipliers are never reused)
        cells = self.phase is Phase.CELLS
        order2 = self.spec.second_order and not cells
        # the second-order rounds end with a round of LPs (reused multipliers may have left
        # the box just below `wide` while the LPs would still contract it much further)
        last = self.last
        ending = (order2 and last is not None and not last.fresh
                  and last.target.family == SECOND_ORDER)
        first = None
        if not ((self.reuse and certs.family == SECOND_ORDER and order2) or ending):
            first = relax(prog, self.lo, self.hi, cell_variables=cells,
                          max_cell_columns=s.rounds.max_cell_columns, rows=self.spec.rows)
            if first is None:
                return None
        wide = order2 and (first is None or first.curvature > s.rounds.wide)
        quad = (relax_quadratic(prog, self.lo, self.hi, s.rounds.prune, rows=self.spec.rows) if wide
                else None)
        if quad is None and first is None:  # (cannot happen: a first round built them)
            return None
        this = _Round(first, quad, True)
        this.fresh = not (self.reuse and certs.usable(this.target))
        return this

    def _fine_relaxation(self) -> tuple[LinearRelaxation, Expansion] | None:
        """The fine rounds' relaxation: with the readings' errors as LP columns where chosen,
        else every product tied by McCormick's inequalities. Where the readings' one cannot
        be built (no readings), McCormick's is taken instead."""
        prog, lo, hi = self.spec.prog, self.lo, self.hi
        if self.phase.readings:
            fine = relax_quadratic_readings(prog, lo, hi,
                                            mccormick=self.phase is Phase.FINE_BOTH,
                                            rows=self.spec.rows)
            if fine is not None:
                return fine
            self.phase = Phase.FINE_MCCORMICK  # (the phase goes on: its rounds not reset)
        return relax_quadratic(prog, lo, hi, prune=0.0, mccormick=True, rows=self.spec.rows)

    # -- 2. certified bounds -----------------------------------------------------------------
    def bounds(self, this: _Round) -> tuple[np.ndarray, np.ndarray]:
        """Certified bounds on the unknowns over this round's relaxation."""
        s, n = self.spec.settings, len(self.ind)
        certs = self.fine_certs if self.phase.fine else self.spec.certs
        if this.fresh and self.phase.fine:
            # where the optima it keeps stand: the fine rounds' optima are checked on the
            # rows left out (strategy/relaxed_check.py; the others' never are). The round's
            # own arrays, not a copy: a box is never written in place once a round has it
            # (`narrow` writes a copy).
            certs.box = (self.lo, self.hi)
        self.skip = self.skip | self.never
        lp = replace(s.lp, workers=self.spec.threads or s.lp.workers)
        if this.quad is None:
            return _bounds(this.target, n, self.skip, certs, this.fresh, lp)
        rel, ex = this.quad
        wide = replace(lp, iterations=s.rounds.wide_iterations, seconds=s.rounds.wide_seconds,
                       tall_simplex=s.rounds.fine_simplex if self.phase.fine else lp.tall_simplex)
        tl, th = _bounds(rel, n, self.skipped_ends(), certs, this.fresh, wide,
                         solver=s.rounds.wide_solver, probes=s.rounds.wide_probes,
                         own_bases=s.rounds.wide_own_bases)
        tl, th = _narrowed_bounds(rel, ex, tl, th, certs, s)
        return to_box(ex, tl, th)

    def skipped_ends(self) -> np.ndarray:
        """Which ends (max, min) of each unknown get no LP this round: those of the unknowns
        sitting out, and in the first fine round, the ends `settled` (see LPRounds)."""
        ends = np.repeat(self.skip[:, None], 2, axis=1)
        if self.phase.fine and self.work.lp_rounds == 0:
            for i, sign in self.spec.settled:
                ends[i, 0 if sign > 0 else 1] = True
        return ends

    # -- 3. narrow the box and propagate -----------------------------------------------------
    def narrow(self, new: tuple[np.ndarray, np.ndarray], this: _Round) -> np.ndarray | None:
        """The box narrowed to the bounds and propagated; each unknown's gain, or None when
        that proved there is no solution."""
        ind, (nlo, nhi) = self.ind, new
        new_lo, new_hi = np.maximum(self.lo[ind], nlo), np.minimum(self.hi[ind], nhi)
        if np.any(new_lo > new_hi):  # certified bounds cross: no solution at all
            k = int(np.flatnonzero(new_lo > new_hi)[0])
            self.emptied = Emptied(self.spec.prog.slots.names[int(ind[k])], None,
                                   "the linear relaxation of all constraints together")
            self.stop = Stop.EMPTY
            self.work = self.work + Work(lp_rounds=int(this.fresh))
            return None
        gains = _gains(self.hi[ind] - self.lo[ind], new_hi - new_lo)
        lo, hi = self.lo.copy(), self.hi.copy()
        lo[ind], hi[ind] = new_lo, new_hi
        spec = self.spec
        res = propagate(spec.prog, tol=max(spec.tol, spec.settings.preliminary_tol),
                        max_sweeps=max(spec.max_sweeps - self.work.sweeps, 0), lo=lo, hi=hi,
                        share=sweep_share(spec.settings), own=True)
        self.lo, self.hi, self.stop = res.lo, res.hi, res.stop
        self.work = self.work + Work(sweeps=res.sweeps)
        if res.status != Status.CONTRACTED:
            self.emptied = res.emptied or Emptied("?", None, None)
        self.moved |= gains >= spec.settings.rounds.stalled
        self.last = this
        return gains

    def record(self, this: _Round) -> None:
        history = self.spec.history
        if history is None or self.emptied is not None:
            return
        n = self.work.lp_rounds + self.work.reused_rounds + 1
        kind = {SECOND_ORDER: "second order", READINGS_FAMILY: "second order, readings as LP "
                "columns"}.get(this.target.family, "first order")
        if self.spec.rows is not None:
            kind += f", {len(self.spec.rows)} working rows"
        history.record(f"LP round {n} ({kind}{'' if this.fresh else ', reused'})",
                       self.lo, self.hi)

    # -- 4. the next round -------------------------------------------------------------------
    def next_round(self, this: _Round, gains: np.ndarray) -> bool:
        """Whether there is a next round, and how it runs."""
        s, best = self.spec.settings.rounds, gains.max(initial=0.0)
        if not this.fresh:  # reused multipliers: again while they pay, else the LPs again
            self.reused_in_a_row += 1
            self.work = self.work + Work(reused_rounds=1)
            self.reuse = best >= s.reuse_gain
            return True
        self.work = self.work + Work(lp_rounds=1, fine_rounds=int(self.phase.fine))
        self.kind_rounds += 1
        limit = self.spec.fine_rounds
        if self.phase.fine and limit is not None and self.work.fine_rounds >= limit:
            return False
        # the next round first tries this round's multipliers, unless its LPs are as cheap
        # as a relaxation (folded first-order rounds), or the second-order phase is over
        # (a round without a first-order relaxation: the second-order one's estimate of the
        # curvature)
        # (not in the fine rounds: there the next box is too close for old multipliers to
        # certify anything narrower, and each try costs an expansion; docs/decisions/12)
        wide = this.quad is not None
        self.reuse = self.phase is Phase.CELLS or (
            wide and not self.phase.fine and (this.first or this.target).curvature > s.wide)
        self.reused_in_a_row = 0
        nxt = next_phase(self.phase, self.measures(this, best), s)
        if nxt is None:
            return False
        self.skip = self.sitting_out(nxt, wide, gains)
        if nxt is not self.phase:
            self.phase, self.kind_rounds = nxt, 0
            self.tried.add(nxt)
            self.reuse = self.reuse and not nxt.fine
        return True

    def measures(self, this: _Round, best: float) -> Measures:
        return Measures(best, this.quad is not None,
                        this.first.remainder_share if this.first is not None else 0.0,
                        self.cellular, self.kind_rounds, frozenset(self.tried),
                        self.spec.fine_start, self.spec.second_order,
                        lambda: self._readings_cost(this))

    def sitting_out(self, nxt: Phase, wide: bool, gains: np.ndarray) -> np.ndarray:
        """The unknowns that sit out the next round's LPs: none after a second-order round
        (rounds of LPs are rare between reused rounds, and one that did not move may move
        after them) or into the fine rounds; into the cell rounds, those no round has
        moved (a parameter known beforehand); else those that gained less than `stalled`
        (`min_gain` in the cell rounds), each tried again a round later."""
        s = self.spec.settings.rounds
        if wide or nxt.fine:
            return np.zeros_like(self.skip)
        if nxt is not self.phase:
            return ~self.moved
        return (gains < (s.min_gain if nxt is Phase.CELLS else s.stalled)) & ~self.skip

    def _readings_cost(self, this: _Round) -> float:
        """The largest share of an unknown's width that the rows' remainders cost its bounds,
        measured from the last LPs' multipliers (of the working rows, on a subset)."""
        assert this.quad is not None
        width = self.hi[self.ind] - self.lo[self.ind]
        cost = self.fine_certs.remainder_cost(this.quad[0], len(self.ind))
        with np.errstate(invalid="ignore", divide="ignore"):
            share = np.where(width > 0, cost / np.where(width > 0, width, 1.0), 0.0)
        return float(share.max(initial=0.0))


def _bounds(rel: LinearRelaxation, n: int, skip: np.ndarray, certs: Certificates,
            fresh: bool, lp: LPSettings, **lp_options: Any) -> tuple[np.ndarray, np.ndarray]:
    """Certified bounds on the relaxation's n main columns: from the multipliers kept in
    `certs` (a matrix product), and unless only those are asked for, from the LPs too (the
    tighter of each pair is kept, and the LPs' multipliers replace the old ones)."""
    lo, hi = reused_bounds(rel, np.eye(n), certs, lp.dense_entries)
    if not fresh:
        return lo, hi
    tl, th = lp_bounds(rel, np.eye(n), lp, skip=skip, certificates=certs, **lp_options)
    return np.maximum(lo, tl), np.minimum(hi, th)


def _narrowed_bounds(rel: LinearRelaxation, ex: Expansion, tl: np.ndarray, th: np.ndarray,
                     certs: Certificates, s: Settings) -> tuple[np.ndarray, np.ndarray]:
    """The bounds [tl, th] of a second-order round, narrowed further with the same
    multipliers: on the relaxation narrowed to them (its product columns bounded by the
    products of the new bounds) they certify narrower bounds, and so on while some unknown
    narrows by `narrowed_gain` (a matrix product each, no new expansion)."""
    n = rel.main
    for _ in range(s.rounds.narrowed_rounds):
        if np.any(tl > th):
            break  # no solution: the caller says so
        lo, hi = reused_bounds(narrowed(rel, ex, tl, th), np.eye(n), certs, s.lp.dense_entries)
        lo, hi = np.maximum(lo, tl), np.minimum(hi, th)
        gain = _gains(th - tl, hi - lo).max(initial=0.0)
        tl, th = lo, hi
        if gain < s.rounds.narrowed_gain:
            break
    return tl, th


def _gains(before: np.ndarray, after: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(before > 0, (before - after) / np.where(before > 0, before, 1), 0.0)
