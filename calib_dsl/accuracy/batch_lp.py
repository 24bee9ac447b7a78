"""Certified bounds of many nearby linear objectives over one relaxation: one LP each,
solved along a path through the objectives so that each starts from its neighbour's optimum.

A prediction's linear part h.p is one objective per predicted coordinate, thousands of them
over the same relaxation. Neither another objective's multipliers nor its optimal basis
bound one objective as tightly as its own LP (the relaxation's projection onto the
parameters has very many vertices, and it is far narrower than the box, so a multiplier
fitted to a neighbour leaves a residual the box charges in full: docs/decisions/22). So every
objective gets its LP, but the objectives are visited in a nearest-neighbour order (a
greedy path on the unit sphere) and HiGHS re-solves from the previous optimum, which a new
cost leaves primal feasible: a few dozen pivots instead of hundreds. Each sign of the
objectives walks the path on its own HiGHS model (its own thread). Every bound is
certified from the LP's multipliers (lp/certify.py), so a stopped or inexact solve only
loosens it; an LP stopped by its limits is solved once more after the walk, from a warm
basis, and which objectives' LPs both ended optimal is returned, so that a caller can bound
the others another way.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

from calib_dsl.accuracy.working_rows import WorkingRows
from calib_dsl.lp.certify import box_maxes_up, certified_maxes
from calib_dsl.lp.highs import infeasible, optimal
from calib_dsl.relax.relaxation import LinearRelaxation
from calib_dsl.settings import Settings

_BLOCK = 2_000_000  # objectives x rows per certified_maxes call (the dense Y's size)


def batch_bounds(rel: LinearRelaxation, objectives: np.ndarray, settings: Settings,
                 directions: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Rigorous [min, max] of each row c of `objectives` (over the relaxation's first
    columns) of c.p over the relaxation, and the LPs' optima (in the relaxation's first
    objectives.shape[1] columns, one row each: points of the relaxation, not proofs) of
    settings.prediction_candidates objectives far apart in direction, both signs.
    `directions` (one a row, default the objectives) order the path and pick those far
    apart: a few leading columns that set the objectives' direction make both cheaper.
    Fourth: per objective, whether both its LPs ended optimal (else its bounds are what a
    stopped LP's multipliers, or the box, certify: valid, but possibly far from tight)."""
    n, cols = len(objectives), rel.A.shape[1]
    C = np.zeros((n, cols))
    C[:, : objectives.shape[1]] = objectives
    upper = box_maxes_up(C, C, rel.lo, rel.hi)
    lower = -box_maxes_up(-C, -C, rel.lo, rel.hi)
    settled = np.ones(n, dtype=bool)
    if n == 0:
        return lower, upper, np.zeros((0, objectives.shape[1])), settled
    near = objectives if directions is None else directions
    order = path(near, settings.prediction_path_window)
    parts = max(1, settings.lp.workers // 2)
    tasks = [(sign, seg) for sign in (1.0, -1.0) for seg in np.array_split(order, parts)
             if len(seg)]
    with ThreadPoolExecutor(max(1, min(settings.lp.workers, len(tasks)))) as pool:
        results = list(pool.map(lambda t: _walk(rel, C, t[0], t[1], settings), tasks))
    wanted = set(spread(near, settings.prediction_candidates))
    points: list[np.ndarray] = []
    for (sign, seg), (ys, solved, found, ended) in zip(tasks, results, strict=True):
        settled[seg] &= ended
        bound = _certified(rel, sign * C[seg[solved]], ys, settings.lp.dense_entries)
        at = seg[solved]
        if sign > 0:
            upper[at] = np.minimum(upper[at], bound)
        else:
            lower[at] = np.maximum(lower[at], -bound)
        points.extend(x for i, x in found if i in wanted)
    X = np.array(points).reshape(len(points), cols)
    return lower, upper, X[:, : objectives.shape[1]], settled


def _walk(rel: LinearRelaxation, C: np.ndarray, sign: float, seg: np.ndarray,
          settings: Settings) -> tuple[np.ndarray, np.ndarray,
                                       list[tuple[int, np.ndarray]], np.ndarray]:
    """The LPs of max sign * c.p for the objectives `seg` (rows of C) in that order, on
    one HiGHS model of the rows the path needs (accuracy/working_rows.py), each from the
    last one's basis (at most settings.prediction_lp_runs runs of the LP's limits each: the
    first, from no basis, can need more pivots than one allows): their multipliers (one row
    per LP that gave some, over all rows), which of seg those are, and the LPs' optima
    feasible for every row (with their objective's row of C), and per objective of seg
    whether its LP ended optimal over every row."""
    lp = settings.lp
    work = WorkingRows(rel, lp, settings.prediction_rows_kept, settings.prediction_rows_added)
    # a new cost leaves the last optimum primal feasible: the primal simplex goes on from it
    work.h.setOptionValue("simplex_strategy", lp.tall_simplex)
    m = rel.A.shape[0]
    ys: dict[int, np.ndarray] = {}
    points: list[tuple[int, np.ndarray]] = []
    ended = np.zeros(len(seg), dtype=bool)
    limits = (lp.seconds, settings.prediction_lp_runs, lp.iterations,
              settings.prediction_row_passes)
    for k in range(len(seg)):
        _solve(work, C, sign, (k, int(seg[k])), limits, ys, points, ended)
    # an LP stopped by its limits (the path's first starts from no basis) is solved once
    # more after the walk, from the last LP's basis, usually near an optimum
    for j in np.flatnonzero(~ended):
        _solve(work, C, sign, (int(j), int(seg[j])), limits, ys, points, ended)
    at = sorted(ys)
    return (np.array([ys[k] for k in at]).reshape(len(at), m), np.array(at, dtype=np.int64),
            points, ended)


def _solve(work: WorkingRows, C: np.ndarray, sign: float, which: tuple[int, int],
           limits: tuple[float, int, int, int], ys: dict[int, np.ndarray],
           points: list[tuple[int, np.ndarray]], ended: np.ndarray) -> None:
    """One LP of _walk: objective `which` = (its place k in the walk, its row i of C), at
    most limits[1] runs of limits[0] seconds and limits[2] pivots in each of at most
    limits[3] passes of the row generation (each adds rows the optimum violates); its
    multipliers into ys[k] (a stopped solve's only where there are none yet), its optimum
    (feasible for every row) into points, ended[k]; ended[k] only once it violates none."""
    k, i = which
    h = work.h
    n = C.shape[1]
    h.changeColsCost(n, np.arange(n, dtype=np.int32), (-sign * C[i]).astype(float))
    done = False
    for _ in range(limits[3]):
        _run(h, limits)
        if not optimal(h):
            break
        more = work.missing(np.asarray(h.getSolution().col_value))
        if not len(more):
            done = True
            break
        work.add(more)
    sol = h.getSolution()
    if sol.dual_valid and (done or k not in ys):  # (a stopped solve's still certify a bound)
        ys[k] = work.multipliers()
    if done and sol.value_valid and h.getInfo().primal_solution_status == 2:
        points.append((i, np.asarray(sol.col_value)))
    ended[k] = ended[k] or done
    work.settle()


def _run(h: Any, limits: tuple[float, int, int, int]) -> None:
    """At most limits[1] runs of limits[0] seconds and limits[2] pivots, until optimal or
    infeasible."""
    seconds, runs, pivots, _ = limits
    raised = False
    for _ in range(runs):  # a run stopped by its time limit goes on from there
        h.setOptionValue("time_limit", h.getRunTime() + seconds)
        h.run()
        if optimal(h) or infeasible(h):
            break
        if _pivot_limited(h):
            # HiGHS does not go on from a run its pivot limit stopped before a feasible
            # basis (another run repeats the same pivots): one more run, allowed every
            # run's pivots at once
            if raised:
                break
            raised = True
            h.setOptionValue("simplex_iteration_limit", pivots * runs)
    if raised:
        h.setOptionValue("simplex_iteration_limit", pivots)


def _pivot_limited(h: Any) -> bool:
    import highspy

    return bool(h.getModelStatus() == highspy.HighsModelStatus.kIterationLimit)


def _certified(rel: LinearRelaxation, C: np.ndarray, Y: np.ndarray,
               dense_entries: int) -> np.ndarray:
    """certified_maxes in blocks (the dense products' size bounded)."""
    out = np.empty(len(C))
    step = max(1, _BLOCK // max(Y.shape[1], 1))
    for a in range(0, len(C), step):
        out[a:a + step] = certified_maxes(rel, C[a:a + step], Y[a:a + step], dense_entries)
    return out


def path(C: np.ndarray, window: int) -> np.ndarray:
    """An order of the rows of C in which each is near the last in direction: the
    objectives sorted along their leading principal direction, cut into windows of
    `window`, and within each a greedy nearest-neighbour path on the unit sphere (from
    where the last window's ended): O(n window) work, not O(n^2)."""
    norms = np.linalg.norm(C, axis=1)
    U = C / np.where(norms > 0, norms, 1.0)[:, None]
    if len(U) > window:
        lead = np.linalg.svd(U - U.mean(axis=0), full_matrices=False)[2][0]
        coarse = np.argsort(U @ lead, kind="stable")
    else:
        coarse = np.arange(len(U))
    order: list[int] = []
    last = None
    for a in range(0, len(U), window):
        block = coarse[a:a + window]
        V = U[block]
        left = np.ones(len(block), dtype=bool)
        cur = 0 if last is None else int(np.argmax(V @ last))
        for _ in range(len(block)):
            left[cur] = False
            order.append(int(block[cur]))
            last = V[cur]
            if not left.any():
                break
            cur = int(np.argmax(np.where(left, V @ last, -np.inf)))
    return np.array(order, dtype=np.int64)


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
