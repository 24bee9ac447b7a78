"""Rigorous bounds from a linear program (Neumaier–Shcherbina).

The LP solver (HiGHS through scipy) works in floating point, so its optimum is never trusted.
Only its dual multipliers are used, as a *certificate*: for any y >= 0 and any p in the box
with A p <= b,

    c.p = y.(A p) + (c - A'y).p  <=  y.b + max over the box of (c - A'y).p,

whatever y is. Every sum is bounded with an explicit rounding-error term, so the bound holds
in exact arithmetic. A poor y gives a poor bound, never a wrong one.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

# Relative rounding-error budget of a float dot product of length <= 10^6 in round-to-nearest
# (gamma_n = n u / (1 - n u) with u = 2^-53, n <= 10^6, is below 1.2e-10): 1e-9 covers it.
_REL = 1e-9
_ABS = 1e-300


@dataclass
class LinearRelaxation:
    """Valid inequalities A p <= b over the box lo <= p <= hi (in exact arithmetic)."""

    A: np.ndarray  # (m, n)
    b: np.ndarray  # (m,)
    lo: np.ndarray  # (n,)
    hi: np.ndarray  # (n,)


def dot_up(x: np.ndarray, y: np.ndarray) -> float:
    """An upper bound on the exact dot product x.y of float vectors."""
    s = float(np.dot(x, y))
    err = float(np.dot(np.abs(x), np.abs(y)))
    return s + _REL * err + _ABS if np.isfinite(err) else (s if np.isinf(s) else np.inf)


def box_max_up(r_lo: np.ndarray, r_hi: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float:
    """An upper bound on max r.p over r in [r_lo, r_hi], p in [lo, hi]."""
    with np.errstate(invalid="ignore"):
        cand = np.stack([r_lo * lo, r_lo * hi, r_hi * lo, r_hi * hi])
    cand = np.where(np.isnan(cand), 0.0, cand)  # 0 * inf: a zero coefficient contributes 0
    terms = cand.max(axis=0)
    s = float(terms.sum())
    return s + _REL * float(np.abs(terms).sum()) + _ABS


def certified_max(rel: LinearRelaxation, c: np.ndarray, y: np.ndarray) -> float:
    """A rigorous upper bound on max c.p over the relaxation, from a dual guess y."""
    y = np.where(np.isfinite(y) & (y > 0), y, 0.0)  # any y >= 0 is a certificate
    used = y > 0
    A, b, y = rel.A[used], rel.b[used], y[used]
    r = c - A.T @ y
    err = _REL * (np.abs(c) + np.abs(A).T @ y) + _ABS  # rounding error of r, componentwise
    return dot_up(y, b) + box_max_up(r - err, r + err, rel.lo, rel.hi)


def lp_bounds(rel: LinearRelaxation, objectives: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rigorous [min, max] of each objective row c.p over the relaxation.

    Where the LP fails (or finds the relaxation infeasible, which we do not certify), the
    bound falls back to the box's own bound on c.p: never wrong, just not tighter.
    """
    from scipy.optimize import linprog

    k = objectives.shape[0]
    lower, upper = np.full(k, -np.inf), np.full(k, np.inf)
    bounds = list(zip(_finite_or_none(rel.lo), _finite_or_none(rel.hi), strict=True))
    for i, c in enumerate(objectives):
        for sign in (1.0, -1.0):  # maximize sign * c.p
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res = linprog(-sign * c, A_ub=rel.A, b_ub=rel.b, bounds=bounds, method="highs")
            if res.status != 0 or res.ineqlin is None:
                bound = box_max_up(sign * c, sign * c, rel.lo, rel.hi)
            else:
                y = -np.asarray(res.ineqlin.marginals)  # HiGHS: <= 0 for a minimization
                bound = certified_max(rel, sign * c, y)
            if sign > 0:
                upper[i] = bound
            else:
                lower[i] = -bound
    return lower, upper


def _finite_or_none(x: np.ndarray) -> list[float | None]:
    return [float(v) if np.isfinite(v) else None for v in x]
