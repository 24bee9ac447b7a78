"""Rigorous bounds from a linear program (Neumaier-Shcherbina).

The LP solver (HiGHS, through its official Python binding highspy) works in floating point,
so its optimum is never trusted. Only its dual multipliers are used, as a *certificate*: for
any y >= 0 and any p in the box with A p <= b,

    c.p = y.(A p) + (c - A'y).p  <=  y.b + max over the box of (c - A'y).p,

whatever y is. Every sum is bounded with an explicit rounding-error term, so the bound holds
in exact arithmetic. A poor y gives a poor bound, never a wrong one.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from scipy import sparse

# Relative rounding-error budget of a float dot product of length <= 10^6 in round-to-nearest
# (gamma_n = n u / (1 - n u) with u = 2^-53, n <= 10^6, is below 1.2e-10): 1e-9 covers it.
_REL = 1e-9
_ABS = 1e-300
LP_SECONDS = 0.2  # per objective: a degenerate LP near the fixed point can crawl


@dataclass
class LinearRelaxation:
    """Valid inequalities A p <= b over the box lo <= p <= hi (in exact arithmetic)."""

    A: sparse.csr_matrix  # (m, n)
    b: np.ndarray  # (m,)
    lo: np.ndarray  # (n,)
    hi: np.ndarray  # (n,)
    main: int = 0  # the first `main` columns are the unknowns; the others nuisance variables
    # for each nuisance column: (configuration id, table column id) of the measured cell whose
    # error it is (ids as in decompose.Slots.cell_row / cell_col)
    cells: np.ndarray | None = None


def dot_up(x: np.ndarray, y: np.ndarray) -> float:
    """An upper bound on the exact dot product x.y of float vectors."""
    s = float(np.dot(x, y))
    err = float(np.dot(np.abs(x), np.abs(y)))
    if not (np.isfinite(s) and np.isfinite(err)):  # overflow: no finite bound to give
        return np.inf
    return s + _REL * err + _ABS


def box_max_up(r_lo: np.ndarray, r_hi: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float:
    """An upper bound on max r.p over r in [r_lo, r_hi], p in [lo, hi]."""
    with np.errstate(invalid="ignore"):
        cand = np.stack([r_lo * lo, r_lo * hi, r_hi * lo, r_hi * hi])
    cand = np.where(np.isnan(cand), 0.0, cand)  # 0 * inf: a zero coefficient contributes 0
    terms = cand.max(axis=0)
    s = float(terms.sum())
    if not np.isfinite(s):  # +inf: unbounded; -inf can only be an overflow
        return np.inf
    return s + _REL * float(np.abs(terms).sum()) + _ABS


def certified_max(rel: LinearRelaxation, c: np.ndarray, y: np.ndarray) -> float:
    """A rigorous upper bound on max c.p over the relaxation, from a dual guess y."""
    y = np.where(np.isfinite(y) & (y > 0), y, 0.0)  # any y >= 0 is a certificate
    used = np.flatnonzero(y > 0)
    A, b, y = rel.A[used], rel.b[used], y[used]
    r = c - A.T @ y
    err = _REL * (np.abs(c) + abs(A).T @ y) + _ABS  # rounding error of r, componentwise
    return dot_up(y, b) + box_max_up(r - err, r + err, rel.lo, rel.hi)


def lp_bounds(rel: LinearRelaxation, objectives: np.ndarray,
              skip: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Rigorous [min, max] of each objective row c.p over the relaxation.

    One HiGHS model is loaded, and each objective re-solved from the previous basis (a few
    pivots each). Where the LP fails (or finds the relaxation infeasible, which we do not
    certify), the bound falls back to the box's own bound on c.p: never wrong, just not
    tighter. Objectives flagged in `skip` get the box bound without an LP.
    """

    k = objectives.shape[0]
    lower, upper = np.full(k, -np.inf), np.full(k, np.inf)
    h = _load(rel)
    n = rel.A.shape[1]
    cols = np.arange(n, dtype=np.int32)
    pad = np.zeros(n - objectives.shape[1])
    for i, c in enumerate(objectives):
        c = np.concatenate([c, pad])  # nuisance columns have no cost
        for sign in (1.0, -1.0):  # maximize sign * c.p, as: minimize -sign * c.p
            box = box_max_up(sign * c, sign * c, rel.lo, rel.hi)
            if skip is not None and skip[i]:
                bound = box
            else:
                h.changeColsCost(n, cols, (-sign * c).astype(float))
                # HiGHS's time limit counts all runs of the object: extend it per solve.
                h.setOptionValue("time_limit", h.getRunTime() + LP_SECONDS)
                h.run()
                # Any y >= 0 certifies a bound, so even a solve stopped by its time limit
                # gives a valid (if weaker) one: only a missing solution is skipped.
                sol = h.getSolution()
                y = -np.asarray(sol.row_dual) if sol.dual_valid else None
                bound = box if y is None else min(box, certified_max(rel, sign * c, y))
            if sign > 0:
                upper[i] = bound
            else:
                lower[i] = -bound
    return lower, upper


def _load(rel: LinearRelaxation) -> Any:
    import highspy
    from scipy import sparse

    h = highspy.Highs()
    h.setOptionValue("output_flag", False)
    m, n = rel.A.shape
    lp = highspy.HighsLp()
    lp.num_col_, lp.num_row_ = n, m
    lp.col_cost_ = np.zeros(n)
    lp.col_lower_ = np.where(np.isfinite(rel.lo), rel.lo, -highspy.kHighsInf)
    lp.col_upper_ = np.where(np.isfinite(rel.hi), rel.hi, highspy.kHighsInf)
    lp.row_lower_ = np.full(m, -highspy.kHighsInf)
    lp.row_upper_ = rel.b.astype(float)
    csc = sparse.csc_matrix(rel.A)
    lp.a_matrix_.format_ = highspy.MatrixFormat.kColwise
    lp.a_matrix_.start_ = csc.indptr.astype(np.int32)
    lp.a_matrix_.index_ = csc.indices.astype(np.int32)
    lp.a_matrix_.value_ = csc.data.astype(float)
    h.passModel(lp)
    return h


def _finite_or_none(x: np.ndarray) -> list[float | None]:
    return [float(v) if np.isfinite(v) else None for v in x]
