"""Exact numbers into floats: the tightest float interval around an exact rational or
decimal, and a float sum rounded one way (the error of a float sum is itself a float,
found by Knuth's two-sum, so the sum moves one float only where it is not exact)."""

from __future__ import annotations

from fractions import Fraction

import numpy as np

from calib_dsl.arith.interval import INF, Arr, dn1, up1


def enclose_fraction(q: Fraction) -> tuple[float, float]:
    """The tightest floats [lo, hi] around q (OverflowError beyond the floats' range)."""
    x = q.numerator / q.denominator  # correctly rounded
    exact = Fraction(x)
    if exact == q:
        return x, x
    if exact < q:
        return x, float(np.nextafter(x, INF))
    return float(np.nextafter(x, -INF)), x


def enclose_decimal(text: str) -> tuple[float, float]:
    """The tightest floats around the exact value of a decimal literal."""
    return enclose_fraction(Fraction(text))


def add_rounded(a: Arr, b: Arr | float, way: float) -> Arr:
    """a + b rounded down (way -1) or up (+1), elementwise; an overflow comes back to the
    largest float (the exact sum is finite)."""
    with np.errstate(invalid="ignore"):
        s = a + b
        t = s - a
        err = (a - (s - t)) + (b - t)  # a + b = s + err exactly (nan where s overflowed)
    rounded = np.where(err * way > 0, np.nextafter(s, way * INF), s)
    if np.all(np.isfinite(s)):
        return rounded
    return np.where(np.isfinite(s), rounded, dn1(s) if way < 0 else up1(s))
