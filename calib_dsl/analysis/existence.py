"""Existence where a point alone cannot prove a row: a row that compares two computed values
(`sqr(m.x[k] - cx) + sqr(m.y[k] - cy) == sqr(radius)`) holds at a point only if both sides
are equal, which interval evaluation can show only for exact points. But such a row's
measured readings may move within their intervals: if the difference of its two sides is
proven positive at one reading vector and negative at another, it is zero somewhere on the
segment between them (intermediate value theorem; the readings' box is convex).

That proof is valid when the readings moved are the row's alone: no other row depends on
its configuration's readings (certify_point.py says which configuration each row uses), and
no row mixes configurations. The two reading vectors: each reading moved by its half-width
in the direction that raises (lowers) the row's difference, the direction found by moving
one reading column at a time (floating point picks the candidates; the signs are proven).
"""

from __future__ import annotations

import numpy as np

from calib_dsl.analysis.certify_point import PointCheck, check_point
from calib_dsl.analysis.readings import Readings
from calib_dsl.ir.program import Program
from calib_dsl.relax.ownership import MIXED


def prove_point(prog: Program, point: np.ndarray, readings: np.ndarray | None = None,
                base: PointCheck | None = None) -> bool:
    """Whether `point` satisfies every constraint of `prog` for some values of its measured
    intervals: by check_point (`base`, if already run with these readings), or where only
    rows comparing two computed values fail, by the intermediate value theorem in their own
    readings."""
    base = base or check_point(prog, point, readings)
    if base.holds:
        return True
    assert base.ok is not None and base.computed is not None
    bad = ~base.ok
    if not base.in_domain or np.any(bad & ~base.computed):
        return False
    if base.owner is None:  # the configuration of each row: only needed from here on
        base = check_point(prog, point, readings, owners=True)
    assert base.owner is not None
    if np.any(base.owner == MIXED):
        return False
    configs = base.owner[bad]
    if np.any(configs < 0):
        return False  # a failing row no reading can move
    rows_of = np.bincount(base.owner[base.owner >= 0])
    if np.any(rows_of[configs] != 1):
        return False  # its readings move other rows too
    r = Readings(prog)
    row_of_config = dict(zip(configs.tolist(), np.flatnonzero(bad).tolist(), strict=True))
    mine = np.array([row_of_config.get(int(c), -1) for c in r.keys // r.ncol])
    moved = mine >= 0  # the readings of the failing rows' configurations
    start = r.middles() if readings is None else readings.copy()
    start[moved] = r.middles()[moved]  # from their middles (they are theirs alone)
    up, down = _directions(prog, point, r, start, moved, mine, base)
    high = _difference(check_point(prog, point, up))
    low = _difference(check_point(prog, point, down))
    rows = np.flatnonzero(bad)
    return bool(np.all(((high[0][rows] > 0) & (low[1][rows] < 0))
                       | ((high[1][rows] < 0) & (low[0][rows] > 0))))


def _difference(check: PointCheck) -> tuple[np.ndarray, np.ndarray]:
    """Per row, the enclosure of computed side minus its other side."""
    assert check.side is not None
    with np.errstate(invalid="ignore"):
        return check.lo - check.side[1], check.hi - check.side[0]


def _directions(prog: Program, point: np.ndarray, r: Readings, start: np.ndarray,
                moved: np.ndarray, mine: np.ndarray, base: PointCheck
                ) -> tuple[np.ndarray, np.ndarray]:
    """The reading vectors that raise and lower each failing row's difference: every moved
    reading at the end of its interval where its row's difference grows (shrinks)."""
    centre = _middle(check_point(prog, point, start))
    cols = r.keys % r.ncol
    slope = np.zeros(len(start))
    for col in np.unique(cols[moved]):
        step = start.copy()
        pick = moved & (cols == col)
        step[pick] = r.middles()[pick] + r.half[pick]
        step = np.clip(step, *r.inside)
        grew = _middle(check_point(prog, point, step)) - centre
        slope[pick] = grew[mine[pick]]
    up, down = start.copy(), start.copy()
    up[moved] = np.where(slope[moved] >= 0, r.inside[1][moved], r.inside[0][moved])
    down[moved] = np.where(slope[moved] >= 0, r.inside[0][moved], r.inside[1][moved])
    return up, down


def _middle(check: PointCheck) -> np.ndarray:
    lo, hi = _difference(check)
    return 0.5 * (lo + hi)
