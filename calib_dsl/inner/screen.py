"""The inner bounds' point checks on the rows that can fail in their box only.

Every candidate point of the inner bounds lies in one box (the result, within the domains).
A checked row whose computed side, enclosed over the whole box with every reading over its
interval (certify_point.box_rows: one interval pass), lies inside its target's exact inside
holds at every point of the box, whatever the readings: no check of a point there can find
it failing. So a point check evaluates only the loop rows (configurations) with a row that
can fail (and the shared part's rows), and the rows left out are filled back in from the
box's pass, in the order a check of every row gives: held (`ok`), no excess, their computed
side the box's enclosure (which holds the point's). The callers compare two checks row by
row on the rows that failed (inner/bounds._pull_back, LinearModel.excess): those were
evaluated at the point, as by a check of every row.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_dsl.analysis.certify_point import PointCheck, box_rows, check_points
from calib_dsl.ir.program import Program, derived


@dataclass(frozen=True)
class Screen:
    """The box's pass (`whole`), the loop rows a point check evaluates (`rows`, increasing)
    and which of the whole check's rows a check of those gives (`mask`)."""

    lo: np.ndarray
    hi: np.ndarray
    whole: PointCheck
    rows: np.ndarray
    mask: np.ndarray


def screen(prog: Program, lo: np.ndarray, hi: np.ndarray) -> Screen | None:
    """The screen of `prog`'s rows over the box [lo, hi] of its independents (made once per
    program and box); None where no loop was compiled once or every loop row can fail."""
    key = f"inner screen {lo.tobytes().hex()}{hi.tobytes().hex()}"
    return derived(prog, key, lambda: _screen(prog, lo, hi))


def _screen(prog: Program, lo: np.ndarray, hi: np.ndarray) -> Screen | None:
    lay = prog.rows
    if lay is None or not len(lay.rows):
        return None
    whole = box_rows(prog, lo, hi)
    assert whole.side is not None and whole.computed is not None
    tlo, thi = whole.side
    with np.errstate(invalid="ignore"):
        # (not `ok`: an implied row is ok at any value; its excess is still reported)
        held = (whole.lo >= tlo) & (whole.hi <= thi) & ~whole.computed
    config = np.where(whole.slots >= lay.shared,
                      (whole.slots - lay.shared) // max(lay.width, 1), -1)
    rows = np.unique(config[~held & (config >= 0)])
    if len(rows) == len(lay.rows):
        return None
    if not len(rows):
        rows = np.zeros(1, dtype=np.int64)  # (a check takes some loop row with the shared)
    return Screen(lo.copy(), hi.copy(), whole, rows, (config < 0) | np.isin(config, rows))


def checks(prog: Program, box: tuple[np.ndarray, np.ndarray], points: np.ndarray,
           readings: np.ndarray) -> list[PointCheck]:
    """check_points(prog, points, readings), of the rows that can fail in `box` only where
    every point lies in it (the others filled in: held)."""
    scr = screen(prog, *box)
    if scr is None or not (np.all(points >= scr.lo) and np.all(points <= scr.hi)):
        return check_points(prog, points, readings)
    part = check_points(prog, points, readings, rows=scr.rows)
    if not np.array_equal(part[0].slots, scr.whole.slots[scr.mask]):
        raise AssertionError("a check of some rows gave other rows than the box's pass")
    return [_filled(scr, c) for c in part]


def _filled(scr: Screen, c: PointCheck) -> PointCheck:
    """The check of every row: `c`'s rows, the others held (from the box's pass)."""
    w, m = scr.whole, scr.mask
    assert c.ok is not None and c.computed is not None and c.side is not None
    assert w.side is not None and w.computed is not None

    def put(base: np.ndarray, part: np.ndarray) -> np.ndarray:
        out = base.copy()
        out[m] = part
        return out

    n = len(w.slots)
    ok = put(np.ones(n, dtype=bool), c.ok)
    return PointCheck(bool(np.all(ok)) and c.in_domain, w.slots, put(w.lo, c.lo),
                      put(w.hi, c.hi), put(np.zeros(n), c.excess), ok,
                      put(w.computed, c.computed),
                      (put(w.side[0], c.side[0]), put(w.side[1], c.side[1])), None,
                      c.in_domain)
