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


def log_limits(values: Any) -> tuple[float, float] | None:
    """Limits of a log axis for these positive widths, spanning at least a decade: widths
    all alike would otherwise be zoomed until their last digits look like differences."""
    import numpy as np

    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v) & (v > 0)]
    if not v.size:
        return None
    lo, hi = float(v.min()) / 1.5, float(v.max()) * 1.5
    return min(lo, hi / 10), hi
