"""Predictions as objectives over the calibration's second-order relaxation.

The prediction program is expanded over the calibration's box exactly as the calibration's
rows were (relax/taylor.py: p = c + w t, t in [-1, 1]^n): each predicted coordinate is

    f(p, q)  in  c0 + c1.t + sum_k c2_k t_i t_j + [-r, r]

with the joint readings' errors inside r. The calibration's relaxation (relax/quadratic.py)
has a column y_k for each product t_i t_j its rows use; every consistent parameter vector
gives a point (t, t_i t_j) of it. So c1.t + c2.y, the products it has no column for charged
at |c2_k| (|t_i t_j| <= 1), is one more linear objective over the same relaxation: its
certified LP bounds (accuracy/batch_lp.py) bound f for every consistent vector, and only the
third-order remainder r is left to the box. The first-order form (accuracy/predict.py) pays
the whole curvature over the box instead, most of a wide calibration box's width.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from calib_dsl.accuracy.batch_lp import batch_bounds
from calib_dsl.arith.interval import dn1, up1
from calib_dsl.ir.program import Program
from calib_dsl.relax.quadratic import FAMILY
from calib_dsl.relax.relaxation import RHS_REL, LinearRelaxation
from calib_dsl.relax.taylor import expand
from calib_dsl.settings import Settings


@dataclass(frozen=True)
class Bounds:
    """Enclosures [lo, hi] of the rows whose target is a measured side (`targets`: those
    slots), each row's gradient in p at the box's centre (`gradient`, the program's
    independents' order) and the LPs' optima (parameter vectors, same order: candidates
    for certified points, not proofs); `value`, where there is one: the rows' models at
    parameter vectors (one a row) as a (rows, vectors) matrix, in floats and without their
    remainders: which vector predicts a row's extreme, not a bound."""

    lo: np.ndarray
    hi: np.ndarray
    targets: np.ndarray
    gradient: np.ndarray
    optima: np.ndarray
    value: Callable[[np.ndarray], np.ndarray] | None = None
    charge: np.ndarray | None = None  # each row's part charged at the box, not the LP's
    # per row: both its LPs ended optimal and its model is finite (None: all); a row not
    # settled is bounded again by the first-order form (accuracy/predict.py)
    settled: np.ndarray | None = None
    # per row: the middles of its derivatives in its configuration's readings (rows, table
    # columns) and that configuration (cell_row id, negative: none or several); where the
    # inner ends' readings are moved to (accuracy/held_readings.py)
    readings: tuple[np.ndarray, np.ndarray] | None = None


def second_order(prog: Program, lo: np.ndarray, hi: np.ndarray, measured: np.ndarray,
                 rel: LinearRelaxation, settings: Settings,
                 first: np.ndarray | None = None) -> Bounds | None:
    """The prediction rows' bounds over the relaxation `rel` (a second-order one over the
    same box: its columns the same t). `lo`, `hi`: the program's slots, its independents at
    the calibration's box, the measured sides 0 (`measured`: which slots those are). None
    where the program has no second-order models or `rel` is not over the same t.
    `first` (by target slot): the first-order form's remainder over the box; only the rows
    whose remainder and products' largest range this form charges less are bounded here
    (on a narrow box the products' columns can cost more than the first order's remainder)."""
    if rel.family != FAMILY or rel.col_keys is None or rel.center is None \
            or rel.scale is None:
        return None
    ex = expand(prog, lo, hi)
    if ex is None or not (np.array_equal(ex.center, rel.center)
                          and np.array_equal(ex.half, rel.scale)):
        return None
    rows = ex.rows.take(np.flatnonzero(measured[ex.rows.slots]))
    n = rel.main
    kept = rel.col_keys[n:] - n  # the products the relaxation has a column for
    if rows.models.c1.shape[1] != n or (len(kept) and kept.max() >= rows.models.c2.shape[1]):
        return None
    if first is not None:
        c2 = np.abs(rows.models.c2).sum(axis=1)
        rows = rows.take(np.flatnonzero(rows.models.r + c2 < first[rows.slots]))
    m = rows.models
    others = np.ones(m.c2.shape[1], dtype=bool)
    others[kept] = False
    # the products without a column, at |t_i t_j| <= 1; sums of non-negative floats rounded up
    slack = (m.r + np.abs(m.c2[:, others]).sum(axis=1)) * (1 + 2.0**-40) + 1e-300
    objectives = np.hstack([m.c1, m.c2[:, kept]])
    # (the gradients set a prediction's direction: the products' terms are small beside them)
    low, high, optima, settled = batch_bounds(rel, objectives, settings, m.c1)
    err = RHS_REL * (np.abs(m.c0) + np.abs(low) + np.abs(high) + slack) + 1e-300
    with np.errstate(invalid="ignore"):
        plo = dn1(dn1(m.c0 + low) - slack) - err
        phi = up1(up1(m.c0 + high) + slack) + err
    ok = np.isfinite(m.c0) & np.isfinite(slack)
    plo, phi = np.where(ok, plo, -np.inf), np.where(ok, phi, np.inf)
    t = np.clip(optima[:, :n], -1.0, 1.0)

    def value(points: np.ndarray) -> np.ndarray:
        t = (points - ex.center) / ex.half
        return (m.c0[:, None] + m.c1 @ t.T
                + m.c2 @ (t[:, ex.pairs.i] * t[:, ex.pairs.j]).T)

    return Bounds(plo, phi, rows.slots, m.c1 / ex.half, ex.center + ex.half * t, value,
                  settled=settled & ok)
