"""A Chebyshev fit: the parameter vector that (locally) minimizes the largest residual, from
the least-squares estimate by linear programs over the model linearized at each step (each
step within a trust region of the domains, FitSettings' chebyshev_*, kept while it lowers
the largest residual). A point and a hope, like least squares: certify_point.py proves
what it claims.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from calib_dsl.analysis.certify_point import check_point, exact_inside
from calib_dsl.analysis.lsq import Linearized, estimate, linearized, rows_at
from calib_dsl.analysis.readings import Readings
from calib_dsl.ir.program import Program
from calib_dsl.lp.highs import minimize
from calib_dsl.relax.layout import independents
from calib_dsl.relax.relaxation import LinearRelaxation, Rows
from calib_dsl.settings import SamplingSettings
from calib_dsl.settings_analysis import FitSettings


def chebyshev(prog: Program, rows: np.ndarray | None = None, normalized: bool = False,
              start: np.ndarray | None = None,
              box: tuple[np.ndarray, np.ndarray] | None = None,
              target: float = 0.0, settle: float = 0.0,
              fits: FitSettings | None = None) -> tuple[np.ndarray, float]:
    """A point with a small largest residual on `rows` (all if None; the others within their
    bounds), and that residual (floating point: the proof comes after); with `normalized`,
    residuals in units of each row's bound. From `start`, else the least-squares estimate
    (`least_squares_start`: a caller with its own sampling settings passes it as `start`);
    within `box` (the unknowns' bounds), else the search domains. Stops early once the
    linearized model cannot bring the largest residual below `target` (its LP's optimum), or
    once a step's largest residual is within `settle` (relative) of what its LP predicted:
    the model is linear there to within that, so another step would gain about as little.
    Its steps and trust region: `fits` (FitSettings' chebyshev_*)."""
    f = fits or FitSettings()
    lo, hi = within_domains(prog, box)
    p = least_squares_start(prog, f) if start is None else start
    p = np.clip(np.where(np.isfinite(p), p, 0.5 * (lo + hi)), lo, hi)
    d, half, jac = rows_at(prog, p)
    rows = np.ones(len(d), dtype=bool) if rows is None else rows
    unit = np.maximum(half, 1e-12) if normalized else np.ones_like(half)
    need = _largest(d, rows, unit)
    width = np.where(np.isfinite(hi - lo), hi - lo, 1.0)
    n, trust = len(p), f.chebyshev_trust
    for _ in range(f.chebyshev_lps):
        # min s  s.t.  -s <= r + J dp <= s on `rows`, |r + J dp| <= their bound elsewhere
        # (r, J: the residuals and their Jacobian, absolute or in bounds)
        r, J = d / unit, jac / unit[:, None]
        A_b, r_b = J[rows], r[rows]
        A_o, r_o, h_o = J[~rows], r[~rows], (half / unit)[~rows]
        ones = np.ones((len(r_b), 1))
        A = np.vstack([np.hstack([A_b, -ones]), np.hstack([-A_b, -ones]),
                       np.hstack([A_o, np.zeros((len(r_o), 1))]),
                       np.hstack([-A_o, np.zeros((len(r_o), 1))])])
        b = np.concatenate([-r_b, r_b, h_o - r_o, h_o + r_o])
        step = trust * width
        x = _minimize(np.r_[np.zeros(n), 1.0], A, b, np.r_[np.maximum(lo - p, -step), 0.0],
                      np.r_[np.minimum(hi - p, step), np.inf])
        if x is None:
            break
        q = np.clip(p + x[:n], lo, hi)
        dq, _, jq = rows_at(prog, q)
        if not _largest(dq, rows, unit) < need * (1 - 1e-6):
            # the model was not linear over the step: a smaller one (where the domains
            # allow large steps along directions the data hardly see, the step's curvature
            # can undo the gain)
            trust *= f.chebyshev_shrink
            if trust < f.chebyshev_min_trust:
                break
            continue
        p, d, jac, need = q, dq, jq, _largest(dq, rows, unit)
        if x[-1] >= target * (1 + 1e-9) > 0 or abs(need - x[-1]) <= settle * need:
            break
    return p, need


def within_domains(prog: Program, box: tuple[np.ndarray, np.ndarray] | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """`box` (the unknowns' bounds; the search domains if None) within the declared domains
    exactly (their floats are rounded outward), so that a point found in it can be certified
    even where it sits at a bound (certify_point.py: a point on a float bound proves
    nothing)."""
    ind = independents(prog)
    lo, hi = box if box is not None else (prog.slots.lo[ind], prog.slots.hi[ind])
    dlo, dhi = exact_inside(prog.slots.lo[ind], prog.slots.hi[ind])
    some = dlo <= dhi
    return (np.where(some, np.maximum(lo, dlo), lo), np.where(some, np.minimum(hi, dhi), hi))


def _minimize(cost: np.ndarray, A: Any, b: np.ndarray, lo: np.ndarray,
              hi: np.ndarray) -> np.ndarray | None:
    """min cost.x subject to A x <= b (A dense or scipy CSR), lo <= x <= hi."""
    rows = (Rows.join(A, np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0), 0)
            if isinstance(A, np.ndarray) else A)
    return minimize(LinearRelaxation(rows, b, lo, hi, len(cost)), cost)


def _largest(d: np.ndarray, rows: np.ndarray, unit: np.ndarray) -> float:
    return float(np.max(np.abs(d / unit)[rows]))


def with_readings(prog: Program, point: np.ndarray, rows: np.ndarray | None = None,
                  box: tuple[np.ndarray, np.ndarray] | None = None,
                  fits: FitSettings | None = None
                  ) -> tuple[np.ndarray, np.ndarray, float] | None:
    """The fit continued from `point` with the joint readings free within their intervals
    (their errors lower the largest residual where the arm's lever is long): steps of linear
    programs in the unknowns and the readings' errors, each within a trust region, kept while
    they lower the largest residual. The point, the readings (Readings order) and the largest
    residual on `rows` (all if None) that the model linearized at the point gives with those
    readings; None when the model has no readings or the LP fails. A point and a hope, as
    above."""
    f = fits or FitSettings()
    readings = Readings(prog)
    if not len(readings.at):
        return None
    lo, hi = within_domains(prog, box)
    width = np.where(np.isfinite(hi - lo), hi - lo, 1.0)
    lin = linearized(prog, point)
    rows = np.ones(len(lin.d), dtype=bool) if rows is None else rows
    best: tuple[np.ndarray, np.ndarray, float] | None = None
    p, trust = point, f.chebyshev_trust
    for _ in range(f.chebyshev_lps):
        got = _readings_step(lin, readings, p, rows, (np.maximum(lo - p, -trust * width),
                                                     np.minimum(hi - p, trust * width)))
        if got is None:
            break
        q = np.clip(p + got[0], lo, hi)
        lin_q = linearized(prog, q)
        merit = _with_errors(lin_q, readings, got[1], rows)
        if best is not None and not merit < best[2] * (1 - 1e-6):
            trust *= f.chebyshev_shrink  # (as in `chebyshev`)
            if trust < f.chebyshev_min_trust:
                break
            continue
        best, p, lin = (q, got[1], merit), q, lin_q
        if abs(merit - got[2]) <= 1e-6 * merit:  # linear to within rounding: done
            break
    if best is None:
        return None
    return best[0], readings.values(best[1]), best[2]


def _readings_step(lin: Linearized, readings: Readings, point: np.ndarray, rows: np.ndarray,
                   step: tuple[np.ndarray, np.ndarray]
                   ) -> tuple[np.ndarray, np.ndarray, float] | None:
    """One LP of `with_readings`: the unknowns' step (within `step`), the readings' errors (in
    half-widths) and the linear model's largest residual on `rows`."""
    from scipy import sparse

    r, c, v = readings.entries(lin)
    m, n, k = len(lin.d), len(point), len(readings.at)
    # columns: the unknowns' steps, the readings' errors (in half-widths), the largest residual
    # rows in units of their bounds (HiGHS's tolerances are absolute: 1e-7 of a metre would
    # swamp the residuals of exact data)
    unit = np.maximum(lin.half, 1e-300)
    B = sparse.csr_matrix((v / unit[r], (r, c)), shape=(m, k))
    J = sparse.hstack([sparse.csr_matrix(lin.jac / unit[:, None]), B]).tocsr()
    t_col = sparse.csr_matrix(np.ones((m, 1)))
    fit, other = np.flatnonzero(rows), np.flatnonzero(~rows)
    A = sparse.vstack([sparse.hstack([J[fit], -t_col[fit]]), sparse.hstack([-J[fit], -t_col[fit]]),
                       sparse.hstack([J[other], 0 * t_col[other]]),
                       sparse.hstack([-J[other], 0 * t_col[other]])]).tocsr()
    d = lin.d / unit
    ones = np.ones(len(other))
    b = np.concatenate([-d[fit], d[fit], ones - d[other], ones + d[other]])
    zlo, zhi = readings.bounds()
    x = _minimize(np.r_[np.zeros(n + k), 1.0], A, b, np.r_[step[0], zlo, 0.0],
                  np.r_[step[1], zhi, np.inf])
    if x is None:
        return None
    scale = float(np.max(lin.half[fit])) if len(fit) else 1.0  # the bound rows share it
    return x[:n], x[n:n + k], float(x[-1]) * scale


def _with_errors(lin: Linearized, readings: Readings, z: np.ndarray, rows: np.ndarray) -> float:
    """The largest residual on `rows` at the point `lin` was made at, the readings at errors
    z (linear in them: their intervals are narrow), in the units `_readings_step` gives it;
    inf where another row leaves its bound."""
    from scipy import sparse

    r, c, v = readings.entries(lin)
    unit = np.maximum(lin.half, 1e-300)
    moved = lin.d / unit + sparse.csr_matrix((v / unit[r], (r, c)),
                                             shape=(len(lin.d), len(z))) @ z
    with np.errstate(invalid="ignore"):
        if np.any(~(np.abs(moved[~rows]) <= 1 + 1e-9)):
            return float("inf")
    scale = float(np.max(lin.half[rows])) if np.any(rows) else 1.0
    return float(np.max(np.abs(moved[rows]), initial=0.0)) * scale


def least_squares_start(prog: Program, fits: FitSettings,
                        sampling: SamplingSettings | None = None) -> np.ndarray:
    """The least-squares estimate a fit starts from (`fits.lsq_evaluations` at most)."""
    return estimate(prog, max_evaluations=fits.lsq_evaluations, sampling=sampling).values


def proven_consistent(prog: Program, fits: FitSettings | None = None,
                      sampling: SamplingSettings | None = None) -> bool:
    """Whether a point is proven to satisfy every row (certify_point.py): the Chebyshev fit
    in units of the rows' bounds, else one more step of it with the joint readings free
    (near the least error the data allow, the readings' freedom can decide whether a point
    fits at all; docs/decisions/16)."""
    start = least_squares_start(prog, fits or FitSettings(), sampling)
    point, need = chebyshev(prog, normalized=True, start=start, fits=fits)
    if need <= 1.0 and check_point(prog, point).holds:
        return True
    step = with_readings(prog, point, fits=fits)
    return step is not None and check_point(prog, step[0], step[1]).holds
