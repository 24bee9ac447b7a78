"""Certified bounds of many nearby linear objectives over one relaxation, with few LPs.

A prediction's linear part h.p is one objective per predicted coordinate, and thousands of
them differ only a little (neighbouring poses). Any multipliers certify a bound on any
objective (lp/certify.py: weak duality, rounding covered): the multipliers y of an LP
solved for c_k bound c as alpha y does, looser by what the box allows (c - alpha c_k).p. So
LPs are solved for a few representatives, every objective takes the multipliers of the one
nearest to it, and the objectives whose bound stays well above what the LPs' optima reach
(a lower estimate of the maximum) become representatives of the next round.
"""

from __future__ import annotations

import numpy as np

from calib_dsl.lp.bounds import lp_solutions
from calib_dsl.lp.certify import box_max_up, certified_maxes
from calib_dsl.relax.relaxation import LinearRelaxation
from calib_dsl.settings import Settings

_BLOCK = 2_000_000  # objectives x rows per certified_maxes call (the dense Y's size)


def batch_bounds(rel: LinearRelaxation, objectives: np.ndarray, settings: Settings
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rigorous [min, max] of each row c of `objectives` (over the relaxation's first
    columns) of c.p over the relaxation, and the LPs' optima (in the relaxation's first
    objectives.shape[1] columns, one row each: points of the relaxation, not proofs)."""
    n, cols = len(objectives), rel.A.shape[1]
    C = np.zeros((n, cols))
    C[:, : objectives.shape[1]] = objectives
    upper = np.array([box_max_up(c, c, rel.lo, rel.hi) for c in C])
    lower = np.array([-box_max_up(-c, -c, rel.lo, rel.hi) for c in C])
    if n == 0:
        return lower, upper, np.zeros((0, objectives.shape[1]))
    width = np.where(np.isfinite(rel.hi - rel.lo), rel.hi - rel.lo, 0.0)
    reps: list[int] = spread(C, settings.prediction_first_lps)
    ys: dict[tuple[int, float], np.ndarray] = {}
    points: list[np.ndarray] = []
    for _ in range(settings.prediction_rounds):
        for i, sign, _, y, point in lp_solutions(rel, C[reps],
                                                 settings.lp):
            ys[(reps[i], sign)] = y
            if point is not None:
                points.append(point)
        for sign, bound in ((1.0, upper), (-1.0, lower)):
            _tighten(rel, C, sign, ys, width, bound, settings.prediction_blend)
        more = _loose(C, lower, upper, points, reps, settings)
        if not more:
            break
        reps = more
    return lower, upper, np.array(points).reshape(len(points), cols)[:, : objectives.shape[1]]


def _tighten(rel: LinearRelaxation, C: np.ndarray, sign: float,
             ys: dict[tuple[int, float], np.ndarray], width: np.ndarray,
             bound: np.ndarray, blend: int) -> None:
    """Each objective's certified max of sign * c.p from its nearest representative's
    multipliers (scaled), or a blend of its `blend` neighbours' (_blends), the tighter taken
    into `bound` where tighter."""
    keys = [k for k in ys if k[1] == sign]
    if not keys:
        return
    R = C[[k for k, _ in keys]]
    Y = np.array([ys[k] for k in keys])
    # alpha: the scale of c_k nearest c; the loss is |c - alpha c_k| times the box's widths
    norms = np.einsum("ij,ij->i", R, R)
    alpha = np.clip((C @ R.T) / np.where(norms > 0, norms, 1.0), 0.0, None)
    best = np.empty(len(C), dtype=np.int64)
    for a in range(0, len(C), 256):
        loss = np.abs(C[a:a + 256, None, :] - alpha[a:a + 256, :, None] * R[None]) @ width
        best[a:a + 256] = np.argmin(loss, axis=1)
    blends = _blends(C, R, width, best, min(len(R), blend))
    step = max(1, _BLOCK // max(Y.shape[1], 1))
    for a in range(0, len(C), step):
        pick = best[a:a + step]
        scale = alpha[np.arange(a, a + len(pick)), pick][:, None]
        found = np.minimum(certified_maxes(rel, sign * C[a:a + step], scale * Y[pick]),
                           certified_maxes(rel, sign * C[a:a + step], blends[a:a + step] @ Y))
        if sign > 0:
            bound[a:a + step] = np.minimum(bound[a:a + step], found)
        else:
            bound[a:a + step] = np.maximum(bound[a:a + step], -found)


def _blends(C: np.ndarray, R: np.ndarray, width: np.ndarray, best: np.ndarray,
            k: int) -> np.ndarray:
    """Per objective, non-negative weights of the representatives (rows of R): c as a
    combination of the k nearest in direction to its nearest one, fitted in the box's
    widths (least squares, weights >= 0): their multipliers so combined bound c where it
    lies between representatives, which one alone bounds only with what the box allows."""
    from scipy.optimize import nnls

    cols = np.flatnonzero(width[: C.shape[1]] > 0)
    w = width[cols]
    norms = np.linalg.norm(R, axis=1)
    U = R / np.where(norms > 0, norms, 1.0)[:, None]
    near = np.argsort(-(U @ U.T), axis=1)[:, :k]  # each representative's k nearest
    out = np.zeros((len(C), len(R)))
    for i, c in enumerate(C):
        ks = near[best[i]]
        try:
            lam, _ = nnls((R[ks][:, cols] * w).T, c[cols] * w, maxiter=50 * k)
        except RuntimeError:  # (no convergence: the nearest one alone stands)
            continue
        out[i, ks] = lam
    return out


def _loose(C: np.ndarray, lower: np.ndarray, upper: np.ndarray, points: list[np.ndarray],
           done: list[int], settings: Settings) -> list[int]:
    """The objectives whose bounds exceed what the LPs' optima reach by more than
    settings.prediction_gap of their width (loosest first, at most prediction_more_lps),
    leaving out those solved already."""
    if not points:
        return []
    X = np.array(points)
    reach = C @ X.T
    hi, lo = reach.max(axis=1), reach.min(axis=1)
    with np.errstate(invalid="ignore"):
        gap = ((upper - hi) + (lo - lower)) / (upper - lower)
    gap[done] = 0.0
    gap[~np.isfinite(gap)] = 0.0
    order = np.argsort(-gap)
    order = order[gap[order] > settings.prediction_gap]
    return [int(i) for i in order[: settings.prediction_more_lps]]


def spread(C: np.ndarray, k: int) -> list[int]:
    """k objectives far apart in direction (farthest-point sampling on the unit sphere)."""
    norms = np.linalg.norm(C, axis=1)
    U = C / np.where(norms > 0, norms, 1.0)[:, None]
    first = int(np.argmax(norms))
    chosen, near = [first], 1.0 - U @ U[first]
    while len(chosen) < min(k, len(C)):
        nxt = int(np.argmax(near))
        if near[nxt] <= 0.0:
            break
        chosen.append(nxt)
        near = np.minimum(near, 1.0 - U @ U[nxt])
    return chosen
