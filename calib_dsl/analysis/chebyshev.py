"""A Chebyshev fit: the parameter vector that (locally) minimizes the largest residual, from
the least-squares estimate by linear programs over the model linearized at each step (each
step within TRUST of the domains, kept while it lowers the largest residual). A point and a
hope, like least squares: certify_point.py proves what it claims.
"""

from __future__ import annotations

import numpy as np

from calib_dsl.analysis.lsq import estimate, residuals
from calib_dsl.ir.program import Program
from calib_dsl.relax.evaluation import Evaluation
from calib_dsl.relax.layout import independents

ITERATIONS = 8  # linear programs lowering the largest residual
TRUST = 0.5  # each LP step within this share of the domains


def bounds_of_rows(prog: Program, p: np.ndarray) -> np.ndarray:
    """Each constraint row's bound (the half-width of its measured side), as lsq divides by."""

    ind = independents(prog)
    lo, hi = prog.slots.lo.copy(), prog.slots.hi.copy()
    lo[ind], hi[ind] = p, p
    rows = Evaluation(prog, lo, hi, ind, p, point=True).run()
    return np.concatenate([0.5 * (r[0][1] - r[0][0]) for r in rows])


def chebyshev(prog: Program, rows: np.ndarray, normalized: bool = False,
              start: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """A point with a small largest residual on `rows` (the others within their bounds), and
    that residual (floating point: the proof comes after); with `normalized`, residuals in
    units of each row's bound. From `start`, else the least-squares estimate."""
    from scipy.optimize import linprog

    ind = independents(prog)
    lo, hi = prog.slots.lo[ind], prog.slots.hi[ind]
    p = estimate(prog, max_evaluations=200).values if start is None else start
    p = np.clip(np.where(np.isfinite(p), p, 0.5 * (lo + hi)), lo, hi)
    half = bounds_of_rows(prog, p)
    unit = np.maximum(half, 1e-12) if normalized else np.ones_like(half)
    best, best_need = p, _need(prog, p, rows, half, unit)
    width = np.where(np.isfinite(hi - lo), hi - lo, 1.0)
    for _ in range(ITERATIONS):
        d, jac = residuals(prog, p)
        # residuals (absolute, or in bounds) and their Jacobian
        r, J = d * half / unit, jac * (half / unit)[:, None]
        n = len(p)
        # min s  s.t.  -s <= r + J dp <= s on the bound's rows, |r + J dp| <= half elsewhere
        A_b, r_b = J[rows], r[rows]
        A_o, r_o, h_o = J[~rows], r[~rows], (half / unit)[~rows]
        ones = np.ones((len(r_b), 1))
        A = np.vstack([np.hstack([A_b, -ones]), np.hstack([-A_b, -ones]),
                       np.hstack([A_o, np.zeros((len(r_o), 1))]),
                       np.hstack([-A_o, np.zeros((len(r_o), 1))])])
        b = np.concatenate([-r_b, r_b, h_o - r_o, h_o + r_o])
        step = TRUST * width
        bounds = [(max(lo[k] - p[k], -step[k]), min(hi[k] - p[k], step[k])) for k in range(n)]
        res = linprog(np.r_[np.zeros(n), 1.0], A_ub=A, b_ub=b, bounds=[*bounds, (0, None)],
                      method="highs")
        if res.status != 0:
            break
        q = np.clip(p + res.x[:n], lo, hi)
        need = _need(prog, q, rows, half, unit)
        if need >= best_need * (1 - 1e-6):
            break
        p, best, best_need = q, q, need
    return best, best_need


def _need(prog: Program, p: np.ndarray, rows: np.ndarray, half: np.ndarray,
          unit: np.ndarray) -> float:
    d, _ = residuals(prog, p)
    return float(np.max(np.abs(d * half / unit)[rows]))
