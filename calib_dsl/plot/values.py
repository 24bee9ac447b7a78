"""Numbers as the result JSON writes them: unbounded ends are the strings "-oo" and "+oo"."""

from __future__ import annotations

import math
from typing import Any


def number(v: Any) -> float:
    if isinstance(v, str):
        return {"-oo": -math.inf, "+oo": math.inf}.get(v, math.nan)
    return float(v)


def width(interval: list[Any] | None) -> float:
    """hi - lo (nan for no interval: an infeasible result)."""
    if interval is None:
        return math.nan
    lo, hi = (number(v) for v in interval)
    return hi - lo
