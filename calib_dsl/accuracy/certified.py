"""Certified inner intervals of predictions: the predicted measurements at the solve's
certified points (parameter vectors proven consistent with the data), so that a prediction's
outer box can be compared with values the model truly takes.

At a certified point p the prediction program is evaluated in interval arithmetic with the
parameters at p and the joint readings at their values (which lie within their errors):
an enclosure [a, b] of the value f(p) the robot's model takes there (certify_point.py's
pass). Over a set of points, the interval [min b, max a] lies inside the hull of those
values, and each of its ends is within rounding of one of them; where it is empty (every
point predicts about the same) there is no inner interval (nan). `inner_hull` takes every
point on every row; `inner_at` takes each row's own two points (the ones an approximate
model puts at that row's extremes, `picks`), evaluated a block of rows at a time, each with
the predicted configuration's readings where `moves` puts them (within their errors, towards
the end it is for: accuracy/held_readings.py), a value the prediction truly takes too.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from calib_dsl.accuracy.held_readings import Moves
from calib_dsl.analysis.certify_point import check_points, reading_slots
from calib_dsl.compile.chunks import chunked
from calib_dsl.ir.program import Program
from calib_dsl.relax.chunked import CHUNK_THREADS, in_threads


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


def inner_at(prog: Program, points: np.ndarray, slots: np.ndarray, picks: np.ndarray,
             block: int, moves: Moves | None = None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """inner_hull's interval for each target slot of `slots`, over only the points its row
    of `picks` names (indices into `points`), which point gave each end ((slots, 2): the
    lower's, the upper's; -1 where there is no interval) and at which readings (a row of
    `moves.configs`, -1: their middles). With `moves`, each pick is evaluated at the
    readings `moves.of` names for it (accuracy/held_readings.py), else at their middles.
    A loop's rows are evaluated `block` rows at a time, each pass at the (point, readings)
    pairs some slot of those rows picked (every point on every row would cost points x
    rows), the passes shared among threads."""
    low, high = np.full(len(slots), np.inf), np.full(len(slots), -np.inf)
    ends = np.full((len(slots), 2), -1, dtype=np.int64)
    read = np.full((len(slots), 2), -1, dtype=np.int64)
    configs = 1 if moves is None else len(moves.configs)
    of = np.zeros_like(picks) if moves is None else moves.of
    lay = prog.rows
    groups: list[tuple[np.ndarray, np.ndarray | None]]
    if lay is None or np.any(slots < lay.shared):  # (no loop compiled once: in one pass)
        groups = [(np.arange(len(slots)), None)]
    else:
        row = (slots - lay.shared) // lay.width
        rows = np.unique(row)
        groups = [(np.flatnonzero(np.isin(row, rows[a:a + block])), rows[a:a + block])
                  for a in range(0, len(rows), block)]

    def evaluated(group: tuple[np.ndarray, np.ndarray | None]) -> tuple:
        mine, rows_ = group
        # (a pair's key: its point and its readings)
        used, which = np.unique(picks[mine] * configs + of[mine], return_inverse=True)
        point, config = used // configs, used % configs
        return mine, which.reshape(len(mine), -1), point, config, _evaluated(
            prog, points[point], slots[mine], rows_, block,
            None if moves is None else moves.configs[config])

    # (the blocks evaluated in threads, joined in their order: relax/chunked.py; one a thread
    # at a time, their enclosures' memory bounded)
    todo = [g for g in groups if len(g[0])]
    done = (r for a in range(0, len(todo), CHUNK_THREADS)
            for r in in_threads(evaluated, todo[a:a + CHUNK_THREADS]))
    for mine, which, point, config, enclosures in done:
        for m in range(which.shape[1]):
            a_end, b_end = enclosures[0][which[:, m], np.arange(len(mine))], \
                enclosures[1][which[:, m], np.arange(len(mine))]
            lower, higher = b_end < low[mine], a_end > high[mine]
            low[mine] = np.where(lower, b_end, low[mine])
            high[mine] = np.where(higher, a_end, high[mine])
            for side, moved in ((0, lower), (1, higher)):
                ends[mine, side] = np.where(moved, point[which[:, m]], ends[mine, side])
                read[mine, side] = np.where(moved, config[which[:, m]], read[mine, side])
    empty = ~(low <= high)
    low[empty], high[empty], ends[empty], read[empty] = np.nan, np.nan, -1, -1
    if moves is None:
        read[:] = -1
    return low, high, ends, read


def _evaluated(prog: Program, points: np.ndarray, slots: np.ndarray, rows: np.ndarray | None,
               block: int, readings: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray]:
    """The computed side's enclosure [lo, hi] of each target slot of `slots` at each point
    ((points, slots) each; nan for a slot no pass evaluated), the readings at `readings`
    (one a point, the whole program's reading_slots order; None: their middles): over
    the program of the loop's rows `rows` (None: the whole program)."""
    out = np.full((2, len(points), len(slots)), np.nan)
    if rows is None:
        checks = check_points(prog, points, readings)
        found, keep = checks[0].slots, np.arange(len(checks[0].slots))
    else:
        assert prog.rows is not None
        chunks = chunked(prog, prog.rows.shared + block * prog.rows.width, rows)
        assert chunks is not None and len(chunks) == 1
        ch = chunks[0]
        mine = None if readings is None else readings[:, np.searchsorted(
            reading_slots(prog), ch.slots(reading_slots(ch.prog)))]
        checks = check_points(ch.prog, points, mine,
                              box=(ch.box(prog.slots.lo), ch.box(prog.slots.hi)))
        keep = np.flatnonzero(ch.kept(checks[0].slots))
        found = ch.slots(checks[0].slots[keep])
    sort = np.argsort(found)
    at = np.minimum(np.searchsorted(found, slots, sorter=sort), len(found) - 1)
    hit = found[sort[at]] == slots
    pos = keep[sort[at]][hit]
    for j, c in enumerate(checks):
        out[0, j, hit], out[1, j, hit] = c.lo[pos], c.hi[pos]
    return out[0], out[1]


def picks(value: Callable[[np.ndarray], np.ndarray], points: np.ndarray) -> np.ndarray:
    """Per row of `value` (rows' approximate predictions at points, one a row: a (rows,
    points) matrix), the points (by place) it puts highest and lowest, as (rows, 2): which
    point's exact prediction each inner end is to be."""
    step = 32  # points at a time: the (rows, points) matrix of many rows stays small
    best, at = None, None
    for a in range(0, len(points), step):
        v = value(points[a:a + step])
        here = np.stack([v.max(axis=1), -v.min(axis=1)], axis=1)
        where = a + np.stack([v.argmax(axis=1), v.argmin(axis=1)], axis=1)
        if best is None or at is None:
            best, at = here, where
            continue
        new = here > best
        best, at = np.where(new, here, best), np.where(new, where, at)
    assert at is not None
    return at


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
