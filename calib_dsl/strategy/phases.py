"""The phases of the rounds of LPs (rounds.py), and which follows which on what measure.

The rounds start with the measurement errors folded into each row (first-order rounds, or
second-order ones while the box is too wide for first order), go on with the errors as LP
columns of their own, then to the fine second-order rounds: every product tied to its
factors by McCormick's inequalities, or the readings' errors as LP columns, or both. Each
round of LPs measures its gains and its relaxation's remainder; `next_phase` reads them and
says which phase the next round runs in, or that the rounds are over.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum

from calib_dsl.settings import RoundsSettings


class Phase(Enum):
    FOLDED = "the errors folded into the rows"
    CELLS = "the errors as LP columns"
    FINE_MCCORMICK = "fine: every product tied by McCormick's inequalities"
    FINE_READINGS = "fine: the readings' errors as LP columns"
    FINE_BOTH = "fine: the readings' errors as LP columns and McCormick's inequalities"

    @property
    def fine(self) -> bool:
        return self in (Phase.FINE_MCCORMICK, Phase.FINE_READINGS, Phase.FINE_BOTH)

    @property
    def readings(self) -> bool:
        """Whether its relaxation keeps the readings' errors as LP columns."""
        return self in (Phase.FINE_READINGS, Phase.FINE_BOTH)


FINE_KINDS = {"readings": Phase.FINE_READINGS, "mccormick": Phase.FINE_MCCORMICK,
              "both": Phase.FINE_BOTH}  # LPRounds.fine_kind: the phase told rounds start in


@dataclass(frozen=True)
class Measures:
    """What a round of LPs measured, and what the rounds know besides."""

    best: float  # the largest gain of an unknown (share of its width)
    wide: bool  # the round was second order (folded while wide, or fine)
    remainder: float  # the first-order relaxation's remainder share of the rows' widths
    cellular: bool  # the errors may be LP columns (few enough measured values)
    kind_rounds: int  # rounds of LPs in this phase so far, this one included
    tried: frozenset[Phase]  # the phases the rounds have run in
    told: bool  # the rounds were told their fine phase (LPRounds.fine_start): they keep it
    second_order: bool  # second-order relaxations are allowed
    # the largest share of an unknown's width the rows' remainders cost its bounds (the
    # last LPs' multipliers times the remainders): measured only when a rule asks
    readings_cost: Callable[[], float]


def next_phase(phase: Phase, m: Measures, s: RoundsSettings) -> Phase | None:
    """The phase of the next round (`phase` itself to go on), or None: the rounds are over."""
    if m.wide:
        if m.best >= (s.fine_min_gain if phase.fine else s.wide_min_gain):
            return phase
        # Neither order contracts this box, unless the other kind of fine rounds may.
        # McCormick's where the readings' first round gained too little: their columns
        # cannot help (exact readings: fixed at 0), and the remainders are the products',
        # which McCormick's inequalities meet (after a gain, the box is where relaxations
        # leave it).
        if phase is Phase.FINE_READINGS and not m.told and m.kind_rounds <= 1:
            return Phase.FINE_MCCORMICK
        # The readings' and McCormick's together where the readings' errors, folded into the
        # rows' remainders, are what holds McCormick's bounds: on many rows with joint
        # readings the remainders' cost is mostly theirs (docs/decisions/10).
        if (phase is Phase.FINE_MCCORMICK and Phase.FINE_BOTH not in m.tried
                and m.readings_cost() >= s.readings_cost):
            return Phase.FINE_BOTH
        return None
    # first order: once the model is linear over the box to within a small part of the
    # data's errors, relaxing again gives the same LP: only the cell columns can still gain
    settled = m.remainder < s.settled
    if phase is Phase.CELLS:
        return _fine(m, s) if m.best < s.min_gain or settled else phase
    if settled and not m.cellular:
        return _fine(m, s)  # the next round would solve the same LP
    if m.best < s.folded_until and not m.cellular:
        # a round with the errors as columns would fold them again (too many): the same
        # relaxation; folded rounds go on while they pay
        return _fine(m, s) if m.best < s.min_gain else phase
    if m.best < s.folded_until or settled:
        return Phase.CELLS  # a tighter relaxation
    return phase


def _fine(m: Measures, s: RoundsSettings) -> Phase | None:
    """The first-order rounds are over: fine second-order rounds follow where their remainder
    is still above `remainder_wide` of the rows' widths (McCormick's), or above
    `remainder_readings` (the readings' errors as LP columns); else the rounds are over."""
    if not m.second_order or m.remainder < s.remainder_readings:
        return None
    return Phase.FINE_READINGS if m.remainder < s.remainder_wide else Phase.FINE_MCCORMICK
