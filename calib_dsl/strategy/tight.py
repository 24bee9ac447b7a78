"""The strategies: `hc4` (the paper's propagation alone) and `tight`.

`tight` is a sequence of contractors: propagation to a small box, rounds of certified LPs
over relaxations of the whole system (strategy/rounds.py), propagation to the fixed point,
then a split of an unknown left wide (strategy/split.py). Propagation first brings the box
down to where the relaxations are accurate; the LPs see all constraints at once, which
propagation cannot. Every LP bound is certified, so the result stays guaranteed. Where the
data see only a combination of parameters (the RX90's r2 + r3), the program is first
rewritten in unknowns along the identifiable combinations (strategy/reparametrize.py): the
same solutions, a tighter relaxation.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from calib_dsl.inner.starts import from_certificates
from calib_dsl.ir.program import Program
from calib_dsl.ir.status import UNKNOWNS
from calib_dsl.lp.certify import Certificates
from calib_dsl.progress import Meter, Progress
from calib_dsl.relax.layout import independents
from calib_dsl.settings import Settings
from calib_dsl.strategy.contractor import Contractor, Propagation, Sequence, sweep_share
from calib_dsl.strategy.history import History
from calib_dsl.strategy.reparametrize import along_combinations, back, pivots
from calib_dsl.strategy.solution import Solution, solution
from calib_dsl.strategy.split import Split
from calib_dsl.strategy.working import WorkingRows

STRATEGIES = ("tight", "hc4")  # the first is the default


def solve_hc4(prog: Program, tol: float = 1e-5, max_sweeps: int = 1000,
              progress: Progress | None = None) -> Solution:
    """Forward-backward propagation to the fixed point (the paper's method)."""
    start = time.perf_counter()
    meter = _meter(prog, progress, start)
    out = Propagation(prog, tol, max_sweeps).contract(prog.slots.lo.copy(), prog.slots.hi.copy())
    if meter is not None and not out.empty:
        meter("propagation", out.lo, out.hi)
    return solution("hc4", out, time.perf_counter() - start)


def solve_tight(prog: Program, tol: float = 1e-5, max_sweeps: int = 1000,
                settings: Settings | None = None, second_order: bool = True, split: bool = True,
                combinations: bool = True, progress: Progress | None = None) -> Solution:
    """The tight strategy on `prog` (in unknowns along the identifiable combinations with
    `combinations`): a box of `prog`, with the bounds of each combination solved for, and
    the widths of `prog`'s declared unknowns after each step (its history). `progress` is
    told the box's total width after each step and each round of LPs."""
    settings = settings or Settings()
    start = time.perf_counter()
    # (a program in new unknowns keeps the old slots at their indices: the same ones recorded)
    history = History(np.array(prog.slots.declared, dtype=np.int64), start)
    history.record("start", prog.slots.lo, prog.slots.hi)
    rep = along_combinations(prog, settings) if combinations else None
    target = rep.prog if rep is not None else prog
    # (the members left as unknowns, like r3, are not cut: the model barely depends on them
    # in the new unknowns)
    uncut = np.array(rep.free, dtype=np.int64) if rep is not None else None
    meter = _meter(target, progress, start)
    certs = Certificates()
    steps = tight_steps(target, tol, max_sweeps, settings, second_order, split, uncut,
                        Watch(meter, history, certs))
    out = steps.contract(target.slots.lo.copy(), target.slots.hi.copy())
    starts = from_certificates(certs, independents(target),
                               pivots(rep) if rep is not None else None)
    if rep is None:
        return solution("tight", out, time.perf_counter() - start, history=history,
                        starts=starts)
    combos = tuple((text, float(out.lo[s]), float(out.hi[s]))
                   for text, s, _, _ in rep.combinations)
    lo, hi = back(rep, out.lo, out.hi)
    pieces = tuple(back(rep, a, b) for a, b in out.pieces)
    return Solution("tight", lo, hi, out.stop, time.perf_counter() - start, out.work,
                    out.emptied, out.split, pieces, combos, history, starts)


@dataclass(frozen=True)
class Watch:
    """What the tight strategy's steps report to and leave behind: the progress meter, the
    history (the box after each step and each round), and the certificates of the LPs
    solved (filled in place; a split's pieces start from the whole box's)."""

    progress: Meter | None = None
    history: History | None = None
    certs: Certificates = field(default_factory=Certificates)


def tight_steps(prog: Program, tol: float, max_sweeps: int, s: Settings,
                second_order: bool = True, split: bool = True,
                uncut: np.ndarray | None = None, watch: Watch | None = None) -> Sequence:
    """The tight strategy's contractors, in order. The rounds and the split share the
    certificates of the LPs solved (`watch.certs`)."""
    watch = watch or Watch()
    certs, progress, history = watch.certs, watch.progress, watch.history
    share = sweep_share(s)
    steps: list[Contractor] = [Propagation(prog, max(tol, s.preliminary_tol), max_sweeps,
                                           share=share)]
    # (on a working set of the rows, grown by the rows the optima violate: working.py)
    steps.append(WorkingRows(prog, s, certs, tol, max_sweeps, second_order, unsolved=uncut,
                             progress=progress, history=history))
    steps.append(Propagation(prog, tol, max_sweeps, share=share))
    if split:
        steps.append(Split(prog, s, certs, tol, max_sweeps, uncut))
    return Sequence(tuple(steps), max_sweeps=max_sweeps, progress=progress,
                    history=history)


def _meter(prog: Program, progress: Progress | None, start: float) -> Meter | None:
    """What reports to `progress` (told the search domains at once), or None: the widths
    are the declared unknowns' (params and vars), as propagation watches them."""
    if progress is None:
        return None
    s = prog.slots
    slots = np.array([i for i in s.declared if s.kinds[i] in UNKNOWNS], dtype=np.int64)
    meter = Meter.over(progress, slots, s.lo, s.hi, start)
    meter("start", s.lo, s.hi)
    return meter
