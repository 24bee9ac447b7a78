"""Which relaxation of the calibration the predictions' LPs run over.

The second-order relaxation (relax/quadratic.py) keeps the model's curvature as
coefficients, but charges each row the joint readings' errors in its remainder, one row at a
time. The first-order one (relax/linearize.py) pays the curvature over the box in its rows'
slack, but keeps each configuration's reading errors as columns its rows share. On a wide
box the curvature is most of a row's width and the second order is the tighter; on a narrow
one (many rows, small errors) the readings' charge widens every row by a share of its data
error, and the extremes of a thin solution set move by several times that share. What each
loses is its remainder share (relax/linearize.py): per row, the part of its width that no
column or data interval carries, as a share of the whole (90th percentile over rows); the
predictions take the relaxation whose share is the smaller.
"""

from __future__ import annotations

import numpy as np

from calib_dsl.ir.program import Program
from calib_dsl.relax.linearize import relax
from calib_dsl.relax.quadratic import relax_quadratic
from calib_dsl.relax.relaxation import LinearRelaxation
from calib_dsl.settings import Settings

Chosen = tuple[LinearRelaxation, np.ndarray | None]  # the relaxation, its centre (second order)


def prediction_relaxation(prog: Program, lo: np.ndarray, hi: np.ndarray,
                          settings: Settings) -> Chosen | None:
    """The calibration's relaxation over the solve's box [lo, hi] (the program's slots) with
    the smaller remainder share, and the second order's centre where it is that one; None
    where neither can be built."""
    fine = relax_quadratic(prog, lo, hi, prune=0.0, mccormick=settings.prediction_mccormick)
    first = relax(prog, lo, hi, max_cell_columns=settings.rounds.max_cell_columns)
    if fine is None:
        return None if first is None else (first, None)
    if first is None or not _shares_readings(first):
        return fine[0], fine[1].center
    rows = fine[1].rows
    second = _share(rows.models.r, 0.5 * (rows.hi - rows.lo))
    return (first, None) if first.remainder_share < second else (fine[0], fine[1].center)


def _share(remainder: np.ndarray, data: np.ndarray) -> float:
    """relax/linearize.py's remainder share of rows with these remainders and data
    half-widths (1 where no row has both finite)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        r = remainder / (remainder + data)
    r = r[np.isfinite(r)]
    return float(np.percentile(r, 90)) if len(r) else 1.0


def _shares_readings(rel: LinearRelaxation) -> bool:
    """Whether the first-order relaxation kept the readings' errors as columns: over
    max_cell_columns it folds them into each row's slack after its share was measured, and
    then charges them row by row as the second order does."""
    return rel.cells is not None and len(rel.cells) > 0
