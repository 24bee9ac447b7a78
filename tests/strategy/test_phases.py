"""The rounds' phases (strategy/phases.py): which phase follows which, on what measure."""

from __future__ import annotations

from dataclasses import replace

import pytest

from calib_dsl.settings import RoundsSettings
from calib_dsl.strategy.phases import Measures, Phase, next_phase

S = RoundsSettings()
NEVER = pytest.fail  # a cost no rule should ask for


def measures(**given: object) -> Measures:
    base = Measures(best=0.5, wide=False, remainder=0.2, cellular=True, kind_rounds=1,
                    tried=frozenset({Phase.FOLDED}), told=False, second_order=True,
                    readings_cost=lambda: NEVER("measured the cost"))
    return replace(base, **given)  # type: ignore[arg-type]


def test_folded_rounds_go_on_while_they_gain_then_take_the_errors_as_columns():
    assert next_phase(Phase.FOLDED, measures(best=S.folded_until * 2), S) is Phase.FOLDED
    assert next_phase(Phase.FOLDED, measures(best=S.folded_until / 2), S) is Phase.CELLS
    # a settled relaxation: the same LP again, so a tighter one
    settled = measures(best=S.folded_until * 2, remainder=S.settled / 2)
    assert next_phase(Phase.FOLDED, settled, S) is Phase.CELLS


def test_without_room_for_cell_columns_the_folded_rounds_lead_to_the_fine_ones():
    few = measures(cellular=False, best=S.min_gain / 2, remainder=S.remainder_wide * 1.5)
    assert next_phase(Phase.FOLDED, few, S) is Phase.FINE_MCCORMICK
    gaining = replace(few, best=(S.min_gain + S.folded_until) / 2)
    assert next_phase(Phase.FOLDED, gaining, S) is Phase.FOLDED


@pytest.mark.parametrize(("remainder", "expected"), [
    (S.remainder_wide * 1.5, Phase.FINE_MCCORMICK),
    ((S.remainder_readings + S.remainder_wide) / 2, Phase.FINE_READINGS),
    (S.remainder_readings / 2, None),
])
def test_the_cell_rounds_end_in_the_fine_rounds_their_remainder_calls_for(remainder, expected):
    over = measures(best=S.min_gain / 2, remainder=remainder)
    assert next_phase(Phase.CELLS, over, S) is expected
    assert next_phase(Phase.CELLS, replace(over, best=S.min_gain * 2,
                                           remainder=S.settled * 2), S) is Phase.CELLS
    assert next_phase(Phase.CELLS, replace(over, second_order=False), S) is None


def test_second_order_rounds_go_on_while_they_gain():
    wide = measures(wide=True, best=S.wide_min_gain * 2)
    assert next_phase(Phase.FOLDED, wide, S) is Phase.FOLDED
    assert next_phase(Phase.FOLDED, replace(wide, best=S.wide_min_gain / 2), S) is None
    fine = replace(wide, best=S.fine_min_gain * 1.01)
    for phase in (Phase.FINE_MCCORMICK, Phase.FINE_READINGS, Phase.FINE_BOTH):
        assert next_phase(phase, fine, S) is phase


def test_the_readings_rounds_that_gain_nothing_at_once_give_way_to_mccormicks():
    stalled = measures(wide=True, best=S.fine_min_gain / 2, kind_rounds=1)
    assert next_phase(Phase.FINE_READINGS, stalled, S) is Phase.FINE_MCCORMICK
    assert next_phase(Phase.FINE_READINGS, replace(stalled, kind_rounds=2), S) is None
    assert next_phase(Phase.FINE_READINGS, replace(stalled, told=True), S) is None


def test_mccormicks_rounds_give_way_to_both_where_the_remainders_cost_much():
    stalled = measures(wide=True, best=S.fine_min_gain / 2, kind_rounds=3,
                       tried=frozenset({Phase.FOLDED, Phase.FINE_MCCORMICK}))
    costly = replace(stalled, readings_cost=lambda: S.readings_cost * 2)
    assert next_phase(Phase.FINE_MCCORMICK, costly, S) is Phase.FINE_BOTH
    cheap = replace(stalled, readings_cost=lambda: S.readings_cost / 2)
    assert next_phase(Phase.FINE_MCCORMICK, cheap, S) is None
    tried = replace(costly, tried=stalled.tried | {Phase.FINE_BOTH})
    assert next_phase(Phase.FINE_MCCORMICK, tried, S) is None
    assert next_phase(Phase.FINE_BOTH, costly, S) is None
