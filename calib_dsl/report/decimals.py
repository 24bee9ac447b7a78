"""Numbers as the report prints them: at the precision the guarantee supports, never
narrower than the proof. An interval's ends are rounded outward at the decimal place where one
unit is at most `QUANTUM_SHARE` of its width (so the printed interval holds the proven one and
is wider by at most that share at each end); a value is its midpoint +- a half-width rounded up
(every value of the interval lies within it). JSON's unbounded ends, "-oo"/"+oo", stay so."""

from __future__ import annotations

import math
from decimal import ROUND_CEILING, ROUND_FLOOR, ROUND_HALF_EVEN, Context, Decimal
from typing import Any

QUANTUM_SHARE = 0.01  # one unit of the last printed place: at most 1 % of the width
POINT_DIGITS = 7  # significant digits of a point (a width of 0: nothing else to go by)
HALF_DIGITS = 3  # significant digits of a half-width (rounded up: at most 1 % more)
MAX_PLACES = 15
EXACT = Context(prec=800)  # wide enough for any two doubles' sum or difference, exactly


def number(v: Any) -> float:
    """A number as the JSON writes it ("-oo", "+oo": unbounded; None: none)."""
    if v is None:
        return math.nan
    if isinstance(v, str):
        return {"-oo": -math.inf, "+oo": math.inf}[v]
    return float(v)


def places(lo: float, hi: float) -> int | None:
    """Decimal places for the interval [lo, hi] (may be negative: tens, hundreds...); None
    when its width gives none (a point, an unbounded interval)."""
    width = hi - lo
    if not (math.isfinite(width) and width > 0):
        return None
    # (the small slack keeps a width of exactly 10**k from asking one place more)
    return min(math.ceil(-math.log10(width * QUANTUM_SHARE) - 1e-9), MAX_PLACES)


def significant(x: float, rounding: str) -> str:
    """x at POINT_DIGITS significant digits, rounded as given."""
    if math.isinf(x):
        return "+oo" if x > 0 else "-oo"
    q = Context(prec=POINT_DIGITS, rounding=rounding).plus(Decimal(x)).normalize()
    return f"{q:f}" if q != 0 else "0"


def rounded(x: float, d: int, rounding: str) -> str:
    """x at d decimal places (d < 0: to tens, hundreds...) with the rounding given."""
    if math.isinf(x):
        return "+oo" if x > 0 else "-oo"
    q = Decimal(x).quantize(Decimal(1).scaleb(-d), rounding=rounding)
    return _plain(q, d)


def _plain(q: Decimal, d: int) -> str:
    if q == 0:
        q = abs(q)  # no "-0.00"
    return f"{q:.{max(d, 0)}f}"


def outward(lo: float, hi: float) -> tuple[str, str]:
    """[lo, hi] printed outward: the printed interval holds [lo, hi]."""
    d = places(lo, hi)
    if d is None:
        return significant(lo, ROUND_FLOOR), significant(hi, ROUND_CEILING)
    return rounded(lo, d, ROUND_FLOOR), rounded(hi, d, ROUND_CEILING)


def inward(lo: float, hi: float) -> tuple[str, str]:
    """[lo, hi] printed inward (a certified inner interval: every printed value is one the
    data truly allow); a point is printed as its nearest value, twice."""
    d = places(lo, hi)
    if d is None:
        return significant(lo, ROUND_HALF_EVEN), significant(hi, ROUND_HALF_EVEN)
    return rounded(lo, d, ROUND_CEILING), rounded(hi, d, ROUND_FLOOR)


def plus_minus(lo: float, hi: float) -> tuple[str, str] | None:
    """(midpoint, half-width) printed so that [lo, hi] lies within midpoint +- half-width;
    None for an unbounded interval."""
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return None
    d = places(lo, hi)
    if d is None:  # a point: its value, to POINT_DIGITS (no proof is printed narrower)
        return significant(lo, ROUND_HALF_EVEN), "0"
    exact = EXACT.divide(EXACT.add(Decimal(lo), Decimal(hi)), 2)
    mid = exact.quantize(Decimal(1).scaleb(-d), rounding=ROUND_HALF_EVEN)
    half = max(EXACT.subtract(Decimal(hi), mid), EXACT.subtract(mid, Decimal(lo)))
    exponent = half.adjusted() - HALF_DIGITS + 1
    half = half.quantize(Decimal(1).scaleb(exponent), rounding=ROUND_CEILING)
    return _plain(mid, d), f"{half:f}" if half.adjusted() >= -MAX_PLACES else f"{half:g}"


def ratio(x: Any) -> str:
    """An outer/inner ratio (>= 1, or "+oo" when the inner interval is a point)."""
    v = number(x)
    if math.isnan(v):
        return ""
    return "+oo" if math.isinf(v) else f"{v:.3f}"


def plain(x: Any, digits: int = 4) -> str:
    """A statistic (not a bound): `digits` significant digits."""
    v = number(x)
    if math.isnan(v):
        return ""
    if math.isinf(v):
        return "+oo" if v > 0 else "-oo"
    return f"{v:.{digits}g}"


def representative(lo: float, hi: float, v: float) -> float:
    """v rounded at the printing place of [lo, hi] (half even), kept inside it when v is:
    the short decimal an export writes for it. A point interval keeps v."""
    d = places(lo, hi)
    if d is None or not math.isfinite(v):
        return v
    quantum = Decimal(1).scaleb(-d)
    x = float(Decimal(v).quantize(quantum, rounding=ROUND_HALF_EVEN))
    if not lo <= v <= hi:
        return x
    if x < lo:
        x = float(Decimal(lo).quantize(quantum, rounding=ROUND_CEILING))
    if x > hi:
        x = float(Decimal(hi).quantize(quantum, rounding=ROUND_FLOOR))
    return x if lo <= x <= hi else v


def clean(x: float, digits: int = 15) -> str:
    """A computed value as a short decimal: `digits` significant digits, so that what float
    arithmetic leaves in the last places (127.30000000000001) is not printed."""
    if not math.isfinite(x):
        return "+oo" if x > 0 else ("-oo" if x < 0 else "nan")
    return repr(float(f"{x:.{digits}g}") + 0.0)  # (no "-0.0")
