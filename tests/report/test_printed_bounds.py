"""What the report prints keeps what is proven: a result's ends rounded away from its inside,
an inner interval's towards it, checked exactly (decimal against the float's own value)."""

from __future__ import annotations

from decimal import Decimal

from hypothesis import given, settings
from hypothesis import strategies as st

from calib_dsl.report.text import printed_interval

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)


def _ends(text: str) -> tuple[Decimal, Decimal]:
    a, b = text[1:-1].split(", ")
    return Decimal(a), Decimal(b)


@settings(max_examples=500, deadline=None)
@given(finite, finite)
def test_outward_ends_hold_the_interval_and_inward_ends_lie_in_it(x, y):
    lo, hi = min(x, y), max(x, y)
    a, b = _ends(printed_interval((lo, hi)))
    assert a <= Decimal(lo) and Decimal(hi) <= b
    c, d = _ends(printed_interval((lo, hi), inward=True))
    assert Decimal(lo) <= c and d <= Decimal(hi)
