"""Contractors as small objects with one protocol, and their composition.

A contractor takes a box (lo, hi over the program's slots) and returns an `Outcome`: a box
holding every solution of the given one, or the proof that there is none (`emptied`), with
the work it did. Strategies compose them as interval libraries do (IBEX, codac): `a & b`
is a `Sequence` (IBEX's CtcCompo), which applies its steps in order, each from the box the
one before left, and stops at the first that proves the box empty; `FixPoint(c, ratio)`
(CtcFixPoint) applies c again while some unknown narrows by more than `ratio` of its width
(and until c says by its own measure that it has no more to give: `Outcome.final`).
`with_budget(sweeps)` is the same contractor allowed that many propagation sweeps.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence as Seq
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from calib_dsl.ir.program import Program
from calib_dsl.ir.status import Status, Stop
from calib_dsl.progress import Meter
from calib_dsl.propagate.diagnose import Emptied
from calib_dsl.propagate.fixpoint import Result, propagate
from calib_dsl.propagate.kernels import Share
from calib_dsl.relax.chunked import in_threads
from calib_dsl.settings import Settings
from calib_dsl.strategy.history import History


@dataclass(frozen=True)
class Work:
    """What a contractor spent: propagation sweeps, rounds of LPs (`fine_rounds` of them the
    fine second-order rounds), and rounds that reused earlier LPs' multipliers instead."""

    sweeps: int = 0
    lp_rounds: int = 0
    reused_rounds: int = 0
    fine_rounds: int = 0

    def __add__(self, other: Work) -> Work:
        return Work(self.sweeps + other.sweeps, self.lp_rounds + other.lp_rounds,
                    self.reused_rounds + other.reused_rounds,
                    self.fine_rounds + other.fine_rounds)

    def __sub__(self, other: Work) -> Work:
        """The work done since `other` (a count taken earlier)."""
        return Work(self.sweeps - other.sweeps, self.lp_rounds - other.lp_rounds,
                    self.reused_rounds - other.reused_rounds,
                    self.fine_rounds - other.fine_rounds)


@dataclass(frozen=True)
class Outcome:
    """A contracted box, or the proof that the box held no solution (`emptied` set)."""

    lo: np.ndarray
    hi: np.ndarray
    stop: Stop  # why the last propagation stopped
    work: Work = Work()
    emptied: Emptied | None = None
    # the unknowns cut into pieces (not identifiable alone), and each piece's box that holds
    # solutions: the box is their hull
    split: tuple[str, ...] = ()
    pieces: tuple[tuple[np.ndarray, np.ndarray], ...] = ()
    # the contractor has no more to give from this box by its own measure: a FixPoint over
    # it stops (and its own outcome is not final: it may be applied again)
    final: bool = False

    @property
    def empty(self) -> bool:
        return self.emptied is not None


def handed(out: Outcome) -> list[np.ndarray]:
    """out's box as a list to pop into a call, `c.contract(box.pop(), box.pop())`, once the
    caller's own name for `out` is gone: the callee then holds the only references, and a
    box it replaces is freed at once (a large program's boxes are held no longer than
    used). A contractor that wraps its given box likewise deletes its parameters."""
    return [out.hi, out.lo]


class Contractor(Protocol):
    @property
    def name(self) -> str: ...

    def contract(self, lo: np.ndarray, hi: np.ndarray) -> Outcome: ...

    def with_budget(self, sweeps: int) -> Contractor: ...

    def __and__(self, other: Contractor) -> Sequence: ...


class Composable:
    """What every contractor shares: `a & b`, the sequence a then b, and `with_budget`, which
    a contractor that propagates overrides (one that does not spends no sweeps: itself)."""

    def with_budget(self, sweeps: int) -> Contractor:
        return self  # type: ignore[return-value]

    def __and__(self, other: Contractor) -> Sequence:
        return Sequence((self, other))  # type: ignore[arg-type]


def from_propagation(res: Result) -> Outcome:
    """The outcome of one call of the propagator."""
    emptied = res.emptied
    if res.status == Status.INFEASIBLE and emptied is None:
        emptied = Emptied("?", None, None)
    return Outcome(res.lo, res.hi, res.stop, Work(sweeps=res.sweeps), emptied)


def sweep_share(settings: Settings) -> Share:
    """A sweep's large steps shared among the chunked passes' threads, as many as the LPs'
    workers (the same box as one thread's: propagate/kernels.py)."""
    threads = settings.lp.workers
    return Share(lambda fn, parts: in_threads(fn, parts, threads), threads,
                 settings.sweep_share)


@dataclass(frozen=True)
class Propagation(Composable):
    """Forward-backward propagation (hc4) to the fixed point, or until a sweep contracts
    every declared unknown by less than `tol`."""

    prog: Program
    tol: float
    max_sweeps: int
    name: str = "propagation"
    share: Share | None = None  # a large step's entries shared among threads (sweep_share)

    def contract(self, lo: np.ndarray, hi: np.ndarray) -> Outcome:
        return from_propagation(propagate(self.prog, tol=self.tol, max_sweeps=self.max_sweeps,
                                          lo=lo, hi=hi, share=self.share))

    def with_budget(self, sweeps: int) -> Propagation:
        return replace(self, max_sweeps=sweeps)


@dataclass(frozen=True)
class Sequence(Composable):
    """Each step from the box the one before left; the work of all of them. The outcome is
    the last step's, with the `stop` of the last step that propagated (a step that did not
    propagate says stop=""). With `max_sweeps`, the sweeps of all the steps together are
    capped: each step that propagates gets what the ones before left, and none runs once
    they are spent (stop="max sweeps"). With `history`, the box after each step is
    recorded there."""

    steps: Seq[Contractor]
    name: str = "sequence"
    max_sweeps: int | None = None
    progress: Meter | None = None  # told the box after each step
    history: History | None = None

    def contract(self, lo: np.ndarray, hi: np.ndarray) -> Outcome:
        out = Outcome(lo, hi, Stop.NONE)
        del lo, hi  # (see `handed`)
        work, stop = Work(), Stop.NONE
        for step in self.steps:
            if self.max_sweeps is not None:
                left = self.max_sweeps - work.sweeps
                if left <= 0:
                    stop = Stop.MAX_SWEEPS
                    break
                step = step.with_budget(left)
            box = handed(out)
            del out
            out = step.contract(box.pop(), box.pop())
            work, stop = work + out.work, out.stop or stop
            if self.history is not None and not out.empty:
                self.history.record(step.name, out.lo, out.hi)
            if out.empty:
                break
            if self.progress is not None:
                self.progress(step.name, out.lo, out.hi)
        return replace(out, work=work, stop=stop)

    def with_budget(self, sweeps: int) -> Sequence:
        return replace(self, max_sweeps=sweeps)

    def __and__(self, other: Contractor) -> Sequence:
        """This sequence with one more step (options kept), or a sequence of it and `other`
        where this one reports (progress, history) or caps sweeps of its own."""
        plain = self.max_sweeps is None and self.progress is None and self.history is None
        return (replace(self, steps=(*self.steps, other)) if plain
                else Sequence((self, other)))


@dataclass(frozen=True)
class FixPoint(Composable):
    """`ctc` applied again from the box it left while some slot narrows by more than `ratio`
    of its width (relative to the box before that application), at most `most` times, and
    until an application says it is `final`; the work of all of them. Without a `ratio`,
    only `ctc`'s own measure (`final`) ends it; without `most`, no count. `progress` is
    told the box after each application, labelled `label` and its number."""

    ctc: Contractor
    ratio: float | None
    most: int | None
    name: str = "fixed point"
    progress: Meter | None = None
    label: str = "round"

    def contract(self, lo: np.ndarray, hi: np.ndarray) -> Outcome:
        out, work = Outcome(lo, hi, Stop.NONE), Work()
        del lo, hi  # (see `handed`)
        for k in itertools.count(1) if self.most is None else range(1, self.most + 1):
            nxt = self.ctc.contract(out.lo, out.hi)
            work = work + nxt.work
            if nxt.empty:
                return replace(nxt, work=work, final=False)
            # (measured now: no box-sized array is held through the next application)
            narrowed = self.ratio is not None and _narrowed(out, nxt, self.ratio)
            out = nxt
            if self.progress is not None:
                self.progress(f"{self.label} {k}", out.lo, out.hi)
            if out.final or (self.ratio is not None and not narrowed):
                break
        return replace(out, work=work, final=False)

    def with_budget(self, sweeps: int) -> FixPoint:
        return replace(self, ctc=self.ctc.with_budget(sweeps))


def _narrowed(before: Outcome, out: Outcome, ratio: float) -> bool:
    """Whether some slot of `out` narrowed by more than `ratio` of its width in `before`."""
    old = before.hi - before.lo
    with np.errstate(invalid="ignore", divide="ignore"):
        gained = np.where(old > 0, 1.0 - (out.hi - out.lo) / old, 0.0)
    return bool(np.any(gained > ratio))
