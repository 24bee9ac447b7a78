"""The inner LP's excess of a failed check (inner/lp.py, LinearModel.excess), read over the
LP's own rows' slots, is what a table of every slot of the program gives."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from calib_dsl.analysis.certify_point import PointCheck
from calib_dsl.inner.lp import LinearModel


def _whole_table(slots, unit, nslots, check):
    plain = ~check.computed
    out = np.zeros(nslots)
    np.maximum.at(out, check.slots[plain],
                  np.where(np.isfinite(check.excess[plain]), check.excess[plain], 0.0))
    failed = np.zeros(nslots, dtype=bool)
    failed[check.slots[check.computed & ~check.ok]] = True
    return out[slots] / unit, failed[slots]


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), nslots=st.integers(1, 30), rows=st.integers(0, 25),
       checked=st.integers(0, 40))
def test_the_excess_over_the_lps_slots_is_the_whole_tables(seed, nslots, rows, checked):
    # LP rows may share a slot, the check has rows the LP lacks and repeats slots, and an
    # excess may be infinite or nan
    rng = np.random.default_rng(seed)
    lp = object.__new__(LinearModel)
    lp.slots = rng.integers(0, nslots, rows)
    lp.unit = rng.uniform(0.5, 2.0, rows)
    lp.nslots = nslots
    excess = rng.normal(size=checked)
    excess[rng.random(checked) < 0.1] = np.inf
    excess[rng.random(checked) < 0.1] = np.nan
    check = PointCheck(False, rng.integers(0, nslots, checked), np.zeros(checked),
                       np.zeros(checked), excess, rng.random(checked) < 0.5,
                       rng.random(checked) < 0.3, (np.zeros(checked), np.zeros(checked)),
                       None, True)
    got, want = lp.excess(check), _whole_table(lp.slots, lp.unit, nslots, check)
    assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
