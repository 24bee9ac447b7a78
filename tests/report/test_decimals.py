"""The report's numbers: printed outward (a guaranteed interval), inward (a certified one)
or as midpoint +- half-width, never narrower than the proof, and no coarser than 1 % of the
width (property tests over random intervals of every magnitude)."""

from __future__ import annotations

import math
from decimal import Decimal

from hypothesis import given
from hypothesis import strategies as st

from calib_dsl.report.decimals import QUANTUM_SHARE, inward, outward, places, plus_minus

finite = st.floats(min_value=-1e9, max_value=1e9, allow_nan=False, allow_infinity=False)
widths = st.floats(min_value=1e-9, max_value=1e6)


def interval(lo: float, w: float) -> tuple[float, float]:
    hi = lo + w
    return (lo, hi) if hi > lo else (lo, math.nextafter(lo, math.inf))


@given(finite, widths)
def test_outward_holds_the_interval_and_is_at_most_one_quantum_wider(lo, w):
    lo, hi = interval(lo, w)
    a, b = outward(lo, hi)
    assert Decimal(a) <= Decimal(lo) and Decimal(b) >= Decimal(hi)
    d = places(lo, hi)
    quantum = Decimal(1).scaleb(-d)
    assert quantum <= Decimal(hi - lo) * Decimal(QUANTUM_SHARE) * Decimal("1.0000001")
    assert Decimal(lo) - Decimal(a) <= quantum and Decimal(b) - Decimal(hi) <= quantum


@given(finite, widths)
def test_inward_lies_within_the_interval(lo, w):
    lo, hi = interval(lo, w)
    a, b = inward(lo, hi)
    assert Decimal(lo) <= Decimal(a) <= Decimal(b) <= Decimal(hi)


@given(finite, widths)
def test_every_value_lies_within_the_midpoint_plus_minus_the_half_width(lo, w):
    lo, hi = interval(lo, w)
    found = plus_minus(lo, hi)
    assert found is not None
    mid, half = (Decimal(x) for x in found)
    assert mid - half <= Decimal(lo) and Decimal(hi) <= mid + half
    quantum = Decimal(1).scaleb(-places(lo, hi))
    assert half <= (Decimal(hi - lo) / 2 + quantum) * Decimal("1.01")


def test_unbounded_ends_and_points():
    assert outward(-5.0, math.inf) == ("-5", "+oo")
    assert outward(-math.inf, math.inf) == ("-oo", "+oo")
    assert plus_minus(-5.0, math.inf) is None
    assert plus_minus(127.30000000000001, 127.30000000000001) == ("127.3", "0")
    assert outward(503.7190952131792, 513.7190952131791) == ("503.7", "513.8")
