"""Proofs of inconsistency sought after a solve that certified no point (strategy/verdict.py).

Within a budget of seconds, in this order:

1. *A row at fault*, where the caller gives the attempt (`at_fault`: outliers/at_fault.py,
   a proof against each row least squares leaves far beyond its bound).
2. *Fine rounds by what they gain.* Rounds of LPs over the result, one of each kind the
   program admits (every product tied by McCormick's inequalities; the readings' errors as
   LP columns with them, where the readings have errors): a kind whose round gains less than
   `fine_min_gain` sits out until another kind's narrows the box that much.
3. *A split.* The box is cut in halves along the unknown widest within its domain, each
   half contracted by propagation and rounds of LPs, and the halves left cut again: the
   data are inconsistent once every piece is proven empty.

Where the solve ran in unknowns along the identifiable combinations (strategy/reparametrize.py:
the solution carries their bounds), the rounds and the split run in those unknowns too, on
the solve's box and the combinations' bounds (`in_solve_unknowns`): the change is exact, so
a proof there is one of the program as written, and the relaxations no longer pay for the
parameters the data cannot separate over their whole domains. The members the change left
free (the model barely depends on them) are not cut.

A step starts only if, at the mean cost of the steps before it (the solve's time before
any), it ends within the budget; the first always starts.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from calib_dsl.analysis.readings import Readings
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.ir.model import Model
from calib_dsl.ir.program import Program
from calib_dsl.lp.certify import Certificates
from calib_dsl.outliers.far import Attempts
from calib_dsl.propagate.diagnose import Emptied
from calib_dsl.relax.layout import independents
from calib_dsl.settings import Settings
from calib_dsl.strategy.contractor import Outcome, Propagation, Sequence
from calib_dsl.strategy.reparametrize import along_combinations
from calib_dsl.strategy.rounds import LPRounds
from calib_dsl.strategy.solution import Solution

# The program without these data rows (ids of Slots.row_keys), on the solve's domains
RowLoader = Callable[[list[int]], Program]
FAILURES = (CalError, ValueError, ArithmeticError, np.linalg.LinAlgError, MemoryError)
KIND_NAMES = {"mccormick": "McCormick's inequalities",
              "both": "the readings' errors as LP columns, and McCormick's inequalities"}


@dataclass(frozen=True)
class Proof:
    emptied: Emptied
    text: str


@dataclass
class Found:
    proof: Proof | None = None
    tried: list[str] = field(default_factory=list)
    far: Attempts = field(default_factory=list)  # the rows far beyond their bound


@dataclass
class Refuter:
    prog: Program
    res: Solution
    model: Model | None
    load: RowLoader | None
    settings: Settings
    tol: float
    max_sweeps: int
    budget: float
    start: float  # the clock's reading when the effort began
    progress: Callable[[str], None] | None = None
    found: Found = field(default_factory=Found)
    box: tuple[np.ndarray, np.ndarray] | None = None  # the result after the fine rounds
    steps: int = 0  # the steps started
    uncut: np.ndarray | None = None  # slots the split leaves whole (members left free)
    # the first attempt, a proof against a row at fault (needs `model` and `load`)
    at_fault: Callable[[Refuter], None] | None = None

    def run(self, far: Attempts) -> Found:
        self.found.far = far
        for attempt in (self._outliers, self._rounds, self._split):
            if self.found.proof is not None:
                break
            try:
                if attempt != self._outliers:
                    self.in_solve_unknowns()
                attempt()
            except FAILURES as err:  # a failure proves nothing: the next attempt runs
                self.found.tried.append(f"{attempt.__name__.strip('_')}: stopped "
                                        f"({type(err).__name__}: {err})")
        return self.found

    def in_solve_unknowns(self) -> None:
        """Move to the unknowns the solve ran in (once): the program along the identifiable
        combinations, on the solve's box (its first slots) and the combinations' certified
        bounds; the new temporaries keep their whole domains. Nothing changes where the
        solve ran in the unknowns as written, or where the change now finds other
        combinations than the solve's."""
        if not self.res.combinations or self.uncut is not None:
            return
        self.uncut = np.zeros(0, dtype=np.int64)  # (tried once, whatever it gives)
        try:
            rep = along_combinations(self.prog, self.settings)
        except FAILURES:  # the effort then runs in the unknowns as written
            return
        if rep is None or [c[0] for c in rep.combinations] != [c[0] for c in
                                                                 self.res.combinations]:
            return
        lo, hi = rep.prog.slots.lo.copy(), rep.prog.slots.hi.copy()
        n = rep.old_slots
        lo[:n], hi[:n] = self.res.lo, self.res.hi
        for (_, a, b), (_, slot, _, _) in zip(self.res.combinations, rep.combinations,
                                              strict=True):
            lo[slot], hi[slot] = max(lo[slot], a), min(hi[slot], b)
        self.prog, self.res = rep.prog, replace(self.res, lo=lo, hi=hi)
        self.uncut = np.array(rep.free, dtype=np.int64)

    # -- the budget ---------------------------------------------------------------------------
    def affords(self, cost: float) -> bool:
        """Whether a step of this cost ends within the budget; the effort's first step always
        starts (`steps` counts those started: `tried` is written after an attempt's steps)."""
        spent = time.perf_counter() - self.start
        self.steps += 1
        if spent + cost <= self.budget or self.steps == 1:
            return True
        self.steps -= 1
        return False

    def say(self, text: str) -> None:
        if self.progress is not None:
            self.progress(text)

    # -- 1. a row at fault -------------------------------------------------------------------
    def _outliers(self) -> None:
        if self.at_fault is not None and self.load is not None and self.model is not None:
            self.at_fault(self)

    # -- 2. fine rounds by their gain -----------------------------------------------------------
    def _rounds(self) -> None:
        kinds = ["mccormick"]
        readings = Readings(self.prog)
        if len(readings.at) and np.any(readings.half > 1e-300):
            kinds.append("both")
        lo, hi = self.res.lo.copy(), self.res.hi.copy()
        ind = independents(self.prog)
        stalled: set[str] = set()
        costs: list[float] = []
        done: dict[str, list[float]] = {k: [] for k in kinds}
        spent: dict[str, list[float]] = {k: [] for k in kinds}  # a kind's rounds cost alike
        while len(stalled) < len(kinds):
            kind = next(k for k in kinds if k not in stalled)
            like = spent[kind] or costs
            if not self.affords(float(np.mean(like)) if like else self.res.seconds):
                break
            t = time.perf_counter()
            self.say(f"verdict: fine rounds ({KIND_NAMES[kind]})")
            out = LPRounds(self.prog, self.settings, Certificates(), self.tol, self.max_sweeps,
                           1, fine_start=True, fine_kind=kind).contract(lo, hi)
            costs.append(time.perf_counter() - t)
            spent[kind].append(costs[-1])
            if out.emptied is not None:
                self.found.proof = Proof(out.emptied, "rounds of LPs over the result's box "
                                         f"({KIND_NAMES[kind]}) proved that it holds no "
                                         "solution")
                self.found.tried.append(f"fine rounds ({KIND_NAMES[kind]}): proven "
                                        f"({sum(costs):.2f} s)")
                return
            gain = float(_gains(hi[ind] - lo[ind], out.hi[ind] - out.lo[ind]).max(initial=0.0))
            done[kind].append(gain)
            lo, hi = out.lo, out.hi
            stalled = {kind} | stalled if gain < self.settings.rounds.fine_min_gain else set()
            if sum(map(len, done.values())) >= self.settings.rounds.max_rounds:
                break
        self.box = (lo, hi)
        for kind, gains in done.items():
            if gains:
                self.found.tried.append(
                    f"fine rounds ({KIND_NAMES[kind]}): {len(gains)}, the largest gain "
                    f"{max(gains):.1%} of an unknown's width, no proof")
        if not costs:
            self.found.tried.append("fine rounds: not tried (the budget was spent)")

    # -- 3. a split ---------------------------------------------------------------------------
    def _split(self) -> None:
        queue = [self.box or (self.res.lo, self.res.hi)]
        costs: list[float] = []
        last: Emptied | None = None
        while queue:
            a, b = queue[0]
            k = self._widest(a, b)
            if k is None or not self.affords(
                    2 * (float(np.mean(costs)) if costs else 0.5 * self.res.seconds)):
                break  # a point not proven empty, or the budget is spent
            queue.pop(0)
            for pa, pb in _halves(a, b, k):
                t = time.perf_counter()
                self.say(f"verdict: split piece {len(costs) + 1}")
                out = self.contract(pa, pb, first_order=False)
                costs.append(time.perf_counter() - t)
                if out.emptied is None:
                    queue.append((out.lo, out.hi))
                else:
                    last = out.emptied
        if not queue and last is not None:
            self.found.proof = Proof(last, f"a split of the result's box into {len(costs)} "
                                     "pieces proved each of them empty")
            self.found.tried.append(f"split: every piece proven empty ({sum(costs):.2f} s)")
        elif costs:
            self.found.tried.append(f"split: {len(costs)} pieces contracted, {len(queue)} "
                                    f"not proven empty ({sum(costs):.2f} s)")
        else:
            self.found.tried.append("split: not tried (the budget was spent)")

    def _widest(self, a: np.ndarray, b: np.ndarray) -> int | None:
        """The slot of the unknown widest within its domain (None: the box is a point)."""
        ind = independents(self.prog)
        if self.uncut is not None:
            ind = ind[~np.isin(ind, self.uncut)]
        dom = self.prog.slots.hi[ind] - self.prog.slots.lo[ind]
        with np.errstate(all="ignore"):
            rel = np.where(dom > 0, (b[ind] - a[ind]) / dom, 0.0)
        rel = np.where(np.isfinite(rel), rel, 0.0)
        return int(ind[int(np.argmax(rel))]) if rel.max(initial=0.0) > 0 else None

    def contract(self, lo: np.ndarray, hi: np.ndarray, first_order: bool) -> Outcome:
        """Propagation and rounds of LPs over all rows on the box [lo, hi]."""
        s = self.settings
        steps = Sequence((Propagation(self.prog, self.tol, self.max_sweeps),
                          LPRounds(self.prog, s, Certificates(), self.tol, self.max_sweeps,
                                   s.split_rounds, second_order=not first_order)),
                         max_sweeps=self.max_sweeps)
        return steps.contract(lo, hi)


def _halves(a: np.ndarray, b: np.ndarray, k: int
            ) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
    mid = 0.5 * (a[k] + b[k])
    lower, upper = b.copy(), a.copy()
    lower[k] = upper[k] = mid
    return (a.copy(), lower), (upper, b.copy())


def _gains(before: np.ndarray, after: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(before > 0, (before - after) / np.where(before > 0, before, 1), 0.0)
