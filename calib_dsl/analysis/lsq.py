"""A least-squares estimate beside the guarantee (scipy's trust-region least squares, a
Levenberg–Marquardt-type method that also respects the search domain).

Every constraint row of the program is a residual: predicted minus measured, divided by the
measurement's tolerance. The estimate is a point and a hope; `solve --lsq` prints it next to
the guaranteed enclosure and checks that it lies inside (a least-squares point can sit outside
when the data are inconsistent with their error bounds, or in a poorly identifiable direction).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_dsl.ir.program import Program
from calib_dsl.relax.evaluation import Evaluation
from calib_dsl.relax.layout import independents


@dataclass
class Estimate:
    names: list[str]
    values: np.ndarray
    rms: float  # root mean square of the normalized residuals (1 = at the error bound)
    worst: float  # largest normalized residual
    converged: bool


def rows_at(prog: Program, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every constraint row at p (floating point): its residual (predicted minus measured),
    its bound (the half-width of its measured side), and the residual's Jacobian."""
    ind = independents(prog)
    lo, hi = prog.slots.lo.copy(), prog.slots.hi.copy()
    lo[ind], hi[ind] = p, p
    rows = Evaluation(prog, lo, hi, ind, p, point=True).run()
    d = np.concatenate([0.5 * (r[0][0] + r[0][1]) for r in rows])
    half = np.concatenate([0.5 * (r[0][1] - r[0][0]) for r in rows])
    jac = np.concatenate([0.5 * (r[1][0] + r[1][1]) for r in rows])
    return d, half, jac


def residuals(prog: Program, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Normalized residuals of every constraint row at p, and their Jacobian."""
    d, half, jac = rows_at(prog, p)
    scale = np.maximum(half, 1e-12)
    return d / scale, jac / scale[:, None]


def estimate(prog: Program, start: np.ndarray | None = None,
             max_evaluations: int = 30) -> Estimate:
    from scipy.optimize import least_squares

    ind = independents(prog)
    names = [prog.slots.names[i] for i in ind]
    lo, hi = prog.slots.lo[ind], prog.slots.hi[ind]
    if start is None:
        start = np.where(np.isfinite(lo) & np.isfinite(hi), 0.5 * (lo + hi),
                         np.clip(0.0, lo, hi))
    cache: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    def both(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        key = p.tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = residuals(prog, p)
        return cache[key]

    # Trust-region reflective keeps the estimate inside the search domain; the problem is
    # nearly linear near its solution, so a few Jacobian evaluations suffice.
    bounds = (np.where(np.isfinite(lo), lo, -np.inf), np.where(np.isfinite(hi), hi, np.inf))
    sol = least_squares(lambda p: both(p)[0], start, jac=lambda p: both(p)[1], bounds=bounds,
                        method="trf", x_scale="jac", max_nfev=max_evaluations)
    r = both(sol.x)[0]
    return Estimate(names, sol.x, float(np.sqrt(np.mean(r**2))) if len(r) else 0.0,
                    float(np.max(np.abs(r))) if len(r) else 0.0, bool(sol.success))
