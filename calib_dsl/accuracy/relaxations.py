"""Which relaxation of the calibration the predictions' LPs run over.

The second-order relaxation (relax/quadratic.py) keeps the model's curvature as
coefficients and charges each row its third-order remainder and the joint readings' errors
through its Taylor arithmetic. The first-order one (relax/linearize.py), its readings folded
into each row (one slab a row over the unknowns alone: the cheapest LP), pays the curvature
over the box and the readings' linear effect. On a wide box the curvature is most of a row's
width and the second order is the tighter; on a narrow one (many rows, small errors) the
second order's charge for the readings is the larger, and the extremes of a thin solution set
move by several times what each row is widened. What a prediction LP feels is how thick each
row's slab is in the unknowns' space: half the row's width over the norm of its unknowns'
coefficients (per unit of each unknown). The predictions take the relaxation whose median
slab is the thinner (the second order's product columns, left out of the measure, only
narrow it further: the measure favours it no less than it should).
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
    """The calibration's relaxation over the solve's box [lo, hi] (the program's slots)
    whose rows are the thinner (module doc), and the second order's centre where it is that
    one; None where neither can be built."""
    fine = relax_quadratic(prog, lo, hi, prune=0.0, mccormick=settings.prediction_mccormick)
    first = relax(prog, lo, hi, cell_variables=False)
    if fine is None:
        return None if first is None else (first, None)
    if first is not None and thickness(first) < thickness(fine[0]):
        return first, None
    return fine[0], fine[1].center


def thickness(rel: LinearRelaxation) -> float:
    """The median over the relaxation's two-sided rows of half the row's width over the
    norm of its coefficients on the unknowns (its first `main` columns, per unit of each
    unknown: `scale` where the columns are scaled); inf where no row has both."""
    A = rel.A
    m = len(rel.b)
    row = np.repeat(np.arange(m), np.diff(A.indptr))
    main = A.indices < rel.main
    scale = np.ones(rel.main) if rel.scale is None else rel.scale[:rel.main]
    coef = A.data[main] / scale[A.indices[main]]
    norm = np.sqrt(np.bincount(row[main], coef * coef, minlength=m))
    b_lo = np.full(m, -np.inf) if rel.b_lo is None else rel.b_lo
    with np.errstate(invalid="ignore", divide="ignore"):
        half = 0.5 * (rel.b - b_lo) / norm
    half = half[np.isfinite(half)]
    return float(np.median(half)) if len(half) else np.inf
