"""Certified inner intervals of predictions: the predicted measurements at the solve's
certified points (parameter vectors proven consistent with the data), so that a prediction's
outer box can be compared with values the model truly takes.

At a certified point p the prediction program is evaluated in interval arithmetic with the
parameters at p and the joint readings at their values (which lie within their errors):
an enclosure [a, b] of the value f(p) the robot's model takes there (certify_point.py's
pass, every point at once). Over the points, the
interval [min b, max a] lies inside the hull of those values, and each of its ends is within
rounding of one of them; where it is empty (every point predicts about the same) there is no
inner interval (nan).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from calib_dsl.analysis.certify_point import check_points
from calib_dsl.ir.program import Program


def inner_hull(prog: Program, points: Sequence[np.ndarray]
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per constraint row, [min over points of the upper end, max of the lower end] of its
    computed side's enclosure at each point (all points evaluated in one pass per block,
    readings at their values; nan where the interval is empty), and the rows' target
    slots. No rows without points."""
    if not points:
        return np.zeros(0), np.zeros(0), np.zeros(0, np.int64)
    checks = check_points(prog, np.array(points))
    targets = checks[0].slots
    low, high = checks[0].hi.copy(), checks[0].lo.copy()
    for c in checks[1:]:
        assert np.array_equal(c.slots, targets)
        low, high = np.fmin(low, c.hi), np.fmax(high, c.lo)
    empty = ~(low <= high)
    low[empty], high[empty] = np.nan, np.nan
    return low, high, targets


def tightness(outer_lo: np.ndarray, outer_hi: np.ndarray, inner_lo: np.ndarray,
              inner_hi: np.ndarray) -> dict[str, float | int | None]:
    """outer width / inner width over the coordinates with a finite outer box and an inner
    interval of positive width: the median and the worst, and how many coordinates had none
    (their ratio is not defined)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        ow, iw = outer_hi - outer_lo, inner_hi - inner_lo
        ok = np.isfinite(ow) & (iw > 0)
        ratio = ow[ok] / iw[ok]
    return {"median_ratio": float(np.median(ratio)) if ratio.size else None,
            "worst_ratio": float(np.max(ratio)) if ratio.size else None,
            "coordinates": int(ok.sum()), "without_inner": int(ow.size - ok.sum())}
