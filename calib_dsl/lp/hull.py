"""The hull of a polytope along some of its coordinates: for each, the LP minimum and maximum
of the coordinate over b_lo <= A x <= b_hi, lo <= x <= hi (HiGHS, one model re-solved for
each objective from the last basis). Not certified: a yardstick (analysis/reference.py) and
a prediction (plan/), never a bound calibc reports as proven.

Besides the hull, which rows hold it: each row's multipliers summed over the LPs (a row with
none at every optimum could be dropped without moving the hull), and the optimal points.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from calib_dsl.lp.highs import MANY_PIVOTS, load, optimal
from calib_dsl.relax.relaxation import LinearRelaxation, Rows


class HullFailed(Exception):
    """An LP of the hull ended without an optimum (an empty or unbounded polytope)."""


@dataclass(frozen=True)
class Hull:
    lo: np.ndarray  # per coordinate asked, its minimum
    hi: np.ndarray  # and maximum
    weight: np.ndarray  # per row, |multiplier| summed over the LPs
    points: np.ndarray  # (2 * coordinates, columns): the minimizers, then the maximizers


def linear_hull(A: Any, b_lo: np.ndarray | None, b_hi: np.ndarray, lo: np.ndarray,
                hi: np.ndarray, columns: Sequence[int] | None = None) -> Hull:
    """The hull along `columns` (all by default) of b_lo <= A x <= b_hi within [lo, hi]
    (infinite entries: no bound)."""
    if not isinstance(A, Rows):
        from scipy import sparse  # (imported only here: a slow import)

        A = sparse.csr_matrix(A)
    m, n = A.shape
    rel = LinearRelaxation(A, np.asarray(b_hi, float), np.asarray(lo, float),
                           np.asarray(hi, float), n,
                           b_lo=None if b_lo is None else np.asarray(b_lo, float))
    h = load(rel, iterations=MANY_PIVOTS, scaling=None)
    cols = list(range(n)) if columns is None else list(columns)
    out = np.empty((2, len(cols)))
    weight = np.zeros(m)
    points = np.empty((2 * len(cols), n))
    every = np.arange(n, dtype=np.int32)
    for side, sign in enumerate((1.0, -1.0)):
        for i, k in enumerate(cols):
            cost = np.zeros(n)
            cost[k] = sign
            h.changeColsCost(n, every, cost)
            h.run()
            if not optimal(h):
                raise HullFailed(f"the hull's LP along column {k} ended without an optimum")
            sol = h.getSolution()
            x = np.asarray(sol.col_value)
            out[side, i] = x[k]
            points[side * len(cols) + i] = x
            weight += np.abs(np.asarray(sol.row_dual))
    return Hull(out[0], out[1], weight, points)
