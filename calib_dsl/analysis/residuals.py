"""Residual ranges: for each measured value, an interval proven to hold the measured value minus
the model's prediction for every parameter vector of a box (a solve's result) and every
reading (joint angle) within its error bound.

A constraint `f(p, q) == m.x[k]` caps f's slot with the cell's interval [m - e, m + e]. With
that slot set to the reading m, the row is f - m, which the mixed mean-value form of the
relaxations (relax/evaluation.py) encloses over the box: D + G (p - p^) + D_q (q - q^), with
|G| times the box's half-widths and |D_q| times the readings' errors, every rounding error
covered (RHS_REL). m - f is its negative. A range wholly outside [-e, e] proves that no
parameter vector of the box fits that measurement: the row is an outlier of the box.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.ir.program import Program
from calib_dsl.relax.chunked import Evaluated, evaluation
from calib_dsl.relax.layout import independents
from calib_dsl.relax.relaxation import RHS_REL


@dataclass(frozen=True)
class Ranges:
    """One entry per measured value of the program: its table, model row (1: the first row
    the table uses), column, the range of measured minus predicted, and its error bound."""

    tables: list[str]
    rows: list[int]
    columns: list[str]
    lo: np.ndarray
    hi: np.ndarray
    bound: np.ndarray
    # per measured value, an upper bound on how much the prediction of a vector of the box
    # moves as the readings move within their error bounds (inf: not known)
    slack: np.ndarray | None = None

    def outside(self) -> np.ndarray:
        """Per measured value: whether its whole range lies outside [-bound, bound]."""
        return (self.lo > self.bound) | (self.hi < -self.bound)


def residual_ranges(prog: Program, box: dict[str, tuple[float, float]]) -> Ranges:
    """The ranges of measured minus predicted of every measured value of `prog` over the box
    (name: (lo, hi), every declared unknown of `prog`)."""
    s = prog.slots
    sides = s.measured_sides or {}
    ind = independents(prog)
    lo, hi = s.lo.copy(), s.hi.copy()
    for k in ind:
        if s.names[k] not in box:
            raise CalError(f"the enclosure has no parameter '{s.names[k]}'")
        lo[k], hi[k] = box[s.names[k]]
    side = np.array(sorted(sides), dtype=np.int64)
    if not len(side):  # no table: nothing measured
        return Ranges([], [], [], np.zeros(0), np.zeros(0), np.zeros(0))
    reading = 0.5 * s.lo[side] + 0.5 * s.hi[side]
    bound = np.maximum(reading - s.lo[side], s.hi[side] - reading)  # e, rounded outward
    lo[side], hi[side] = reading, reading
    f_lo, f_hi, slack = _row_ranges(prog, lo, hi, ind, side)
    assert s.row_keys is not None and s.col_keys is not None
    keys = [sides[int(k)] for k in side]
    return Ranges([s.row_keys[r][0] for r, _ in keys], [s.row_keys[r][1] for r, _ in keys],
                  [s.col_keys[c][1] for _, c in keys], -f_hi, -f_lo, bound, slack)


def _row_ranges(prog: Program, lo: np.ndarray, hi: np.ndarray, ind: np.ndarray,
                side: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Enclosures of f - m over the box for the rows whose target is one of `side` (the
    first row of each: a cell capped twice keeps its first constraint's). A side no row
    targets (its constraint became a merge of slots, as y == q where x = 0) gets the whole
    line: sound, and no claim."""
    ranges = row_enclosures(prog, lo, hi, ind)
    first: dict[int, int] = {}
    for i, t in enumerate(ranges.ev.targets().tolist()):
        first.setdefault(t, i)
    pick = np.array([first.get(int(k), -1) for k in side], dtype=np.int64)
    none = pick < 0
    if len(ranges.lo) == 0:  # (every side is then one no row targets)
        f_lo = f_hi = slack = np.zeros(len(side))
    else:
        at = np.maximum(pick, 0)
        f_lo, f_hi, slack = ranges.lo[at], ranges.hi[at], ranges.slack[at]
    return (np.where(none, -np.inf, f_lo), np.where(none, np.inf, f_hi),
            np.where(none, np.inf, slack))


@dataclass(frozen=True)
class RowEnclosures:
    """Per constraint row of an Evaluation over a box: an enclosure of its residual over the
    whole box (the mean-value form, rounded outward), and the Evaluation (its rows' targets
    and sources)."""

    lo: np.ndarray
    hi: np.ndarray
    ev: Evaluated
    # per row, a bound on its change as the readings move within their error bounds
    slack: np.ndarray = field(default_factory=lambda: np.zeros(0))


def row_enclosures(prog: Program, lo: np.ndarray, hi: np.ndarray,
                   ind: np.ndarray, owners: bool = False) -> RowEnclosures:
    center = 0.5 * (lo[ind] + hi[ind])
    ev = evaluation(prog, lo, hi, center, owners=owners)
    rows = ev.run()
    if not rows:
        return RowEnclosures(np.zeros(0), np.zeros(0), ev)
    dlo, dhi = (np.concatenate([r[0][i] for r in rows]) for i in (0, 1))
    gmax = np.concatenate([np.maximum(np.abs(r[1][0]), np.abs(r[1][1])) for r in rows])
    qmax = np.concatenate([np.maximum(np.abs(r[2][0]), np.abs(r[2][1])) for r in rows])
    w = np.maximum(center - lo[ind], hi[ind] - center) * (1 + 4 * RHS_REL)
    with np.errstate(invalid="ignore"):  # 0 * inf: an unbounded unknown a row ignores
        moved = qmax @ ev.e if qmax.shape[1] else np.zeros(len(dlo))
        spread = gmax @ w + moved
    spread = np.where(np.isnan(spread), np.inf, spread)
    err = RHS_REL * (spread + np.abs(dlo) + np.abs(dhi)) + 1e-300
    moved = np.where(np.isnan(moved), np.inf, moved) * (1 + 4 * RHS_REL) + 1e-300
    return RowEnclosures(dlo - spread - err, dhi + spread + err, ev, moved)
