"""The least-squares point of the accuracy statement: a Levenberg–Marquardt fit in numpy,
started near the fit (the load's least-squares estimate, else the certified centre), kept in
the search domain by projection.

`solve --lsq` fits with scipy (analysis/lsq.py); the statement runs in every solve, where
importing scipy.optimize alone would cost a small model most of its inner bounds' time, so
it polishes a near point itself. A fit that stops on its budget is said to be so
(`converged` False), never passed off as the optimum.
"""

from __future__ import annotations

import numpy as np

from calib_dsl.analysis.lsq import Estimate, Linearized, evaluated, normalized
from calib_dsl.ir.program import Program
from calib_dsl.relax.layout import independents
from calib_dsl.settings import Settings

Seen = dict[bytes, Linearized]  # a point's bytes -> every row there (floating point)


def polish(prog: Program, start: np.ndarray, settings: Settings,
           seen: Seen | None = None, rows: Linearized | None = None) -> Estimate:
    """The least-squares point from `start` (independents' order): damped Gauss-Newton steps
    scaled by the Jacobian's columns (Marquardt), each projected onto the domains and taken
    only when it lowers the sum of squares; stopped when one lowers it by at most
    settings.fit_tolerance of it, or when the linearized rows expect no more than that and
    a step confirms it. `rows`: every row at `start` with its Jacobian, made
    already (a fit's, Estimate.rows). `seen`, if given, is given the rows at the start and
    at the result (the statement's residuals there: each evaluation of every row of a large
    campaign costs as much as a step)."""
    ind = independents(prog)
    names = [prog.slots.names[k] for k in ind]
    lo, hi = prog.slots.lo[ind], prog.slots.hi[ind]
    x = np.clip(start, lo, hi)

    if (rows is not None and np.array_equal(x, start)
            and rows.jac.shape == (len(rows.d), len(ind))):
        (r, jac), kept = normalized(rows), rows
    else:
        r, jac, kept = evaluated(prog, x)
    if seen is not None:
        seen[x.tobytes()] = kept
    if not (np.all(np.isfinite(r)) and np.all(np.isfinite(jac))):
        return Estimate(names, x, float("inf"), float("inf"), False)
    cost, damping, converged = float(r @ r), settings.fit_damping, False
    for _ in range(settings.fit_steps):
        scale = np.maximum(np.linalg.norm(jac, axis=0), 1e-300)
        step = _step(jac, r, scale, damping)
        trial = np.clip(x + step, lo, hi)
        # the linearized rows' gain: one within the tolerance says x is the optimum (the
        # gradient of the sum of squares vanishes), which the trial confirms when it lowers
        # the sum by no more; it is then evaluated without its Jacobian (half the cost)
        model = r + jac @ (trial - x)
        final = cost - float(model @ model) <= settings.fit_tolerance * float(model @ model)
        tr, tj, tlin = evaluated(prog, trial, jacobian=not final)
        tcost = float(tr @ tr) if np.all(np.isfinite(tr)) else np.inf
        if final and cost - tcost <= settings.fit_tolerance * min(cost, tcost):
            if tcost < cost:
                x, r, cost, kept = trial, tr, tcost, tlin
            converged = True
            break
        if final and tcost < cost:  # (a larger gain than expected: on, with the Jacobian)
            tr, tj, tlin = evaluated(prog, trial)
            tcost = float(tr @ tr) if np.all(np.isfinite(tr)) else np.inf
        if tcost < cost and np.all(np.isfinite(tj)):
            gain = cost - tcost
            x, r, jac, cost, kept = trial, tr, tj, tcost, tlin
            damping = max(damping / 3.0, 1e-12)
            if gain <= settings.fit_tolerance * cost:
                converged = True
                break
        else:
            damping *= 4.0
            # a step that no damping makes smaller than the floats' resolution: at the optimum
            if np.all(np.abs(trial - x) <= 1e-15 * np.maximum(np.abs(x), 1.0)):
                converged = True
                break
    if seen is not None:
        seen[x.tobytes()] = kept
    n = max(len(r), 1)
    return Estimate(names, x, float(np.sqrt(cost / n)) if len(r) else 0.0,
                    float(np.max(np.abs(r))) if len(r) else 0.0, converged)


def _step(jac: np.ndarray, r: np.ndarray, scale: np.ndarray, damping: float) -> np.ndarray:
    """The step minimizing |J s + r|^2 + damping |D s|^2, D the columns' norms: solved as
    one least-squares system (rank-deficient Jacobians of unidentifiable parameters too)."""
    a = np.vstack([jac, np.sqrt(damping) * np.diag(scale)])
    b = np.concatenate([-r, np.zeros(len(scale))])
    return np.linalg.lstsq(a, b, rcond=None)[0]
