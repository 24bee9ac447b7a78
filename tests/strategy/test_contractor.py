"""The contractor algebra (strategy/contractor.py): `a & b` is the sequence a then b,
`FixPoint(c, ratio)` applies c until no slot narrows by more than `ratio` of its width, and
`with_budget(sweeps)` caps a contractor's propagation sweeps, whatever contractor it is."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from calib_dsl.pipeline import load
from calib_dsl.propagate.diagnose import Emptied
from calib_dsl.strategy.contractor import (
    Composable,
    FixPoint,
    Outcome,
    Propagation,
    Sequence,
    Work,
)
from calib_dsl.strategy.history import History

ARM = Path(__file__).resolve().parents[2] / "models" / "examples" / "planar_arm.cal"


@dataclass(frozen=True)
class Shrink(Composable):
    """Moves every upper bound towards the lower by `factor` of the width, `times` times
    (then leaves the box as it is); empty on call `empty_at` if given. Counts its calls."""

    factor: float
    times: int
    empty_at: int | None = None
    calls: list[int] = field(default_factory=list)
    name: str = "shrink"

    def contract(self, lo: np.ndarray, hi: np.ndarray) -> Outcome:
        self.calls.append(len(self.calls) + 1)
        n = len(self.calls)
        if n == self.empty_at:
            return Outcome(lo, hi, "empty", Work(lp_rounds=1), Emptied("x", None, None))
        if n > self.times:
            return Outcome(lo, hi, "", Work(lp_rounds=1))
        return Outcome(lo, lo + (1 - self.factor) * (hi - lo), "", Work(lp_rounds=1))


@settings(max_examples=60, deadline=None)
@given(factor=st.sampled_from([0.0, 0.05, 0.2, 0.5, 0.9]),
       ratio=st.sampled_from([0.01, 0.1, 0.3]), times=st.integers(0, 6), most=st.integers(1, 10))
def test_a_fixpoint_stops_when_no_slot_gains_more_than_its_ratio(factor, ratio, times, most):
    ctc = Shrink(factor, times)
    lo, hi = np.zeros(3), np.array([1.0, 2.0, 0.0])
    out = FixPoint(ctc, ratio, most).contract(lo, hi)
    # each call that shrinks gains `factor` of every width; the first one that gains no
    # more than the ratio is the last, or the `most`-th
    gaining = times if factor > ratio else 0
    assert len(ctc.calls) == min(most, gaining + 1)
    assert out.work.lp_rounds == len(ctc.calls)
    shrunk = min(len(ctc.calls), times)
    assert np.allclose(out.hi, hi * (1 - factor) ** shrunk) and np.array_equal(out.lo, lo)


def test_a_fixpoint_ends_at_the_proof_of_emptiness():
    ctc = Shrink(0.5, 10, empty_at=3)
    out = FixPoint(ctc, 0.01, 10).contract(np.zeros(2), np.ones(2))
    assert out.empty and len(ctc.calls) == 3 and out.work.lp_rounds == 3


@dataclass(frozen=True)
class Counted(Composable):
    """Halves the box's widths; says it is final on call `final_at` (its own measure)."""

    final_at: int
    calls: list[int] = field(default_factory=list)
    name: str = "counted"

    def contract(self, lo: np.ndarray, hi: np.ndarray) -> Outcome:
        self.calls.append(len(self.calls) + 1)
        return Outcome(lo, lo + 0.5 * (hi - lo), "", Work(lp_rounds=1),
                       final=len(self.calls) == self.final_at)


@settings(max_examples=30, deadline=None)
@given(final_at=st.integers(1, 12), most=st.none() | st.integers(1, 12),
       ratio=st.none() | st.sampled_from([0.1, 0.9]))
def test_a_fixpoint_stops_where_its_contractor_says_it_is_final(final_at, most, ratio):
    """The contractor's own measure ends the fixed point as a ratio or a count does; a
    fixed point's outcome is never final itself (it may be applied again)."""
    ctc = Counted(final_at)
    out = FixPoint(ctc, ratio, most).contract(np.zeros(2), np.ones(2))
    gaining = 1 if ratio == 0.9 else final_at  # (each call gains a half of every width)
    assert len(ctc.calls) == min(final_at, most or final_at, gaining)
    assert out.work.lp_rounds == len(ctc.calls) and not out.final
    assert np.allclose(out.hi, 0.5 ** len(ctc.calls))


def test_work_counts_since():
    a, b = Work(3, 2, 1, 1), Work(5, 4, 2, 1)
    assert b - a == Work(2, 2, 1, 0) and a + (b - a) == b


def test_and_composes_sequences():
    a, b, c = Shrink(0.5, 1), Shrink(0.5, 1), Shrink(0.5, 1)
    seq = a & b & c
    assert isinstance(seq, Sequence) and seq.steps == (a, b, c)
    out = seq.contract(np.zeros(1), np.ones(1))
    assert out.hi[0] == 0.125 and out.work.lp_rounds == 3
    recorded = Sequence((a,), history=History(np.array([0])))
    assert (recorded & b).steps == (recorded, b)  # (its history stays its own)


def test_a_budget_caps_the_sweeps_of_every_step():
    prog = load(ARM)
    p = Propagation(prog, 0.0, 1000)
    assert p.with_budget(3).max_sweeps == 3
    assert Shrink(0.5, 1).with_budget(3) is not None  # (no sweeps of its own: itself)
    free = (p & p).contract(prog.slots.lo.copy(), prog.slots.hi.copy())
    for cap in (1, 2, max(1, free.work.sweeps - 1)):
        out = Sequence((p, p), max_sweeps=cap).contract(prog.slots.lo.copy(),
                                                      prog.slots.hi.copy())
        assert out.work.sweeps <= cap
    fixed = FixPoint(p, 0.0, 5).with_budget(2)
    assert isinstance(fixed, FixPoint) and fixed.ctc.max_sweeps == 2
