"""Rounds of LPs on a sample of a long table's rows, checked on all of them.

A laser tracker's campaign has thousands of configurations that repeat one another: the LPs'
bounds rest on a few rows each (an optimum of 23 unknowns has at most 23 binding rows), and
a relaxation of all rows costs the sample's times rows / sample. So the rounds run on an
evenly spread sample to its fixed point (second order included), then one round relaxes
every row in first order: its certified bounds narrow the box, and the rows its LPs bind on
(nonzero multipliers) join the sample, which runs to its fixed point again, while a round on
all rows narrowed some unknown by `sample_gain` (`sample_passes` rounds on all rows at
most). Propagation always runs on every row.

Every relaxation, of any rows, holds every solution: a sample only loses tightness, and the
round on all rows recovers what the sample missed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_dsl.ir.program import Program
from calib_dsl.lp.bounds import lp_bounds
from calib_dsl.lp.certify import Certificates
from calib_dsl.progress import Meter
from calib_dsl.propagate.diagnose import Emptied
from calib_dsl.propagate.fixpoint import propagate
from calib_dsl.relax.layout import independents
from calib_dsl.relax.linearize import relax_evaluated
from calib_dsl.settings import Settings
from calib_dsl.strategy.contractor import Outcome, Work
from calib_dsl.strategy.history import History
from calib_dsl.strategy.rounds import LPRounds


@dataclass(frozen=True)
class SampledRounds:
    """The rounds on a sample and on all rows (a contractor); `sample`: loop row indices."""

    prog: Program
    settings: Settings
    tol: float
    max_sweeps: int
    sample: np.ndarray
    second_order: bool = True
    unsolved: np.ndarray | None = None
    progress: Meter | None = None
    history: History | None = None
    name: str = "rounds of LPs"

    def contract(self, lo: np.ndarray, hi: np.ndarray) -> Outcome:
        s, rows, work = self.settings, self.sample, Work()
        out = Outcome(lo, hi, "")
        for passes in range(s.sample_passes + 1):
            sampled = LPRounds(self.prog, s, Certificates(), self.tol,
                               self.max_sweeps - work.sweeps, s.max_rounds, self.second_order,
                               unsolved=self.unsolved, progress=self.progress,
                               history=self.history, rows=rows)
            out = sampled.contract(out.lo, out.hi)
            work = work + out.work
            if out.empty or work.sweeps >= self.max_sweeps or passes == s.sample_passes:
                break
            full, binding, gain = self._all_rows(out.lo, out.hi, work)
            work = work + full.work
            out = full
            if out.empty or gain < s.sample_gain:
                break
            grown = np.union1d(rows, binding)
            if len(grown) == len(rows):
                break  # the sample has every row the LPs bind on: its rounds would repeat
            rows = grown
        return Outcome(out.lo, out.hi, out.stop, work, out.emptied)

    def _all_rows(self, lo: np.ndarray, hi: np.ndarray, work: Work
                  ) -> tuple[Outcome, np.ndarray, float]:
        """One round of first-order LPs over every row, then propagation: the box, the loop
        rows the LPs bound on, and the largest gain of an unknown (its share of its width)."""
        s, prog = self.settings, self.prog
        none = np.zeros(0, dtype=np.int64)
        done = relax_evaluated(prog, lo, hi, cell_variables=False)
        if done is None:
            return Outcome(lo, hi, ""), none, 0.0
        rel, ev = done
        ind = independents(prog)
        skip = np.isin(ind, self.unsolved) if self.unsolved is not None else None
        certs = Certificates()
        nlo, nhi = lp_bounds(rel, np.eye(len(ind)), skip=skip, certificates=certs,
                             iterations=s.lp_iterations, seconds=s.lp_seconds,
                             threads=s.lp_workers)
        new_lo, new_hi = np.maximum(lo[ind], nlo), np.minimum(hi[ind], nhi)
        if np.any(new_lo > new_hi):  # certified bounds cross: no solution at all
            k = int(np.flatnonzero(new_lo > new_hi)[0])
            crossed = Emptied(prog.slots.names[int(ind[k])], None,
                              "the linear relaxation of all constraints together")
            return Outcome(lo, hi, "empty", Work(lp_rounds=1), crossed), none, 0.0
        before = hi[ind] - lo[ind]
        with np.errstate(invalid="ignore", divide="ignore"):
            gain = float(np.max(np.where(before > 0, (before - (new_hi - new_lo))
                                         / np.where(before > 0, before, 1.0), 0.0),
                                initial=0.0))
        lo, hi = lo.copy(), hi.copy()
        lo[ind], hi[ind] = new_lo, new_hi
        res = propagate(prog, tol=max(self.tol, s.preliminary_tol),
                        max_sweeps=max(self.max_sweeps - work.sweeps, 0), lo=lo, hi=hi)
        emptied: Emptied | None = None
        if res.status != "contracted":
            emptied = res.emptied or Emptied("?", None, None)
        if self.history is not None and emptied is None:
            self.history.record("LP round (first order, all rows)", res.lo, res.hi)
        if self.progress is not None and emptied is None:
            self.progress("LP round on all rows", res.lo, res.hi)
        binding = _binding_rows(prog, certs, ev.targets())
        return (Outcome(res.lo, res.hi, res.stop, Work(sweeps=res.sweeps, lp_rounds=1),
                        emptied), binding, gain)


def _binding_rows(prog: Program, certs: Certificates, targets: np.ndarray) -> np.ndarray:
    """The loop rows whose constraints have a nonzero multiplier in some LP of `certs` (the
    relaxation's rows are the evaluation's rows `keys`, compared with `targets`)."""
    lay = prog.rows
    if lay is None or not certs.y:
        return np.zeros(0, dtype=np.int64)
    slots = targets[certs.bound_keys()]
    slots = slots[slots >= lay.shared]
    return np.unique((slots - lay.shared) // lay.width)
