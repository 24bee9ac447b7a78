"""Rigorous bounds from a linear program (Neumaier-Shcherbina).

The LP solver (HiGHS, through its official Python binding highspy) works in floating point,
so its optimum is never trusted. Only its dual multipliers are used, as a *certificate*: for
any y >= 0 and any p in the box with A p <= b,

    c.p = y.(A p) + (c - A'y).p  <=  y.b + max over the box of (c - A'y).p,

whatever y is. Every sum is bounded with an explicit rounding-error term, so the bound holds
in exact arithmetic. A poor y gives a poor bound, never a wrong one. With c = 0 the same
bound below 0 proves that no p satisfies the rows: an infeasible LP's dual ray is such a y.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

from calib_dsl.lp.certify import Certificates, box_bounds, box_max_up, certified_max, tighten
from calib_dsl.lp.highs import (
    DUAL_SIMPLEX,
    RowCheck,
    add_rows,
    current_basis,
    infeasible,
    load,
    optimal,
    set_basis,
    starting_rows,
)
from calib_dsl.relax.relaxation import LinearRelaxation
from calib_dsl.settings import LPSettings


def lp_bounds(rel: LinearRelaxation, objectives: np.ndarray, lp: LPSettings | None = None,
              skip: np.ndarray | None = None, solver: str = "simplex",
              certificates: Certificates | None = None,
              probes: bool = False, own_bases: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Rigorous [min, max] of each objective row c.p over the relaxation.

    Each worker thread loads one HiGHS model and re-solves it for its share of the objectives
    from the previous basis (a few pivots each); HiGHS releases the GIL, so the workers run on
    separate cores. Where the LP finds the relaxation infeasible and its dual ray proves it
    (`_farkas`), the share's bound is -inf: the bounds cross. Where the LP fails otherwise,
    the bound falls back to the box's own bound on c.p: never wrong, just not tighter.
    Objectives flagged in `skip` get the box bound without an LP (a column of flags per
    objective, or two: its max's and its min's). `lp.iterations` and
    `lp.seconds` limit each solve (a run stopped by them still certifies a bound). `solver` is
    HiGHS's: "simplex" re-solves from the last basis; "ipm" (interior point, no crossover)
    starts afresh each time but costs the same few dozen iterations on any objective, which
    pays on a large LP whose objectives are far apart (their multipliers certify all the same).
    The multipliers of each LP solved are kept in `certificates` if given (for
    reused_bounds on a later box). With `probes`, a few probe LPs first find points on many
    box bounds at once (_probe_points): worth it far from the solution only. With `own_bases`
    (and `certificates`), the simplex starts each objective from that objective's last basis
    kept there; without, from the optimum of the objective its worker solved before.
    `lp.workers`: how many workers (each with its own HiGHS model) share the objectives.
    """
    lp = lp or LPSettings()
    lower, upper, signed = box_bounds(rel, objectives)
    ends = np.zeros((len(objectives), 2), dtype=bool) if skip is None else \
        np.broadcast_to(skip.reshape(len(objectives), -1 if len(objectives) else 2),
                        (len(objectives), 2))
    tasks = [t for t in signed if not ends[t[0], 0 if t[1] > 0 else 1]]
    workers = max(1, min(lp.workers, len(tasks)))
    points = _probe_points(rel, tasks, lp) if probes and workers > 1 else []
    # both signs of an objective in the same share: the second starts from the first's optimum
    share_of = {i: k % workers for k, i in enumerate(dict.fromkeys(t[0] for t in tasks))}
    shares = [[t for t in tasks if share_of[t[0]] == w] for w in range(workers)]
    if workers == 1:
        results = [_solve_share(rel, shares[0], lp, solver, certificates,
                                own_bases=own_bases)]
    else:
        with ThreadPoolExecutor(workers) as pool:
            results = list(pool.map(lambda share: _solve_share(rel, share, lp, solver,
                                                                    certificates, points,
                                                                    own_bases),
                                    shares))
    for share in results:
        for i, sign, bound, y, basis, point in share:
            if certificates is not None:
                certificates.record(rel, i, sign, y, basis, point)
            if y is not None:  # (None: the box bound stands, and only a basis is kept)
                tighten(lower, upper, i, sign, bound)
    return lower, upper


def _solve_share(rel: LinearRelaxation, share: list, lp: LPSettings,
                 solver: str = "simplex",
                 certificates: Certificates | None = None,
                 probes: list[tuple[np.ndarray, tuple | None]] | None = None,
                 own_bases: bool = True) -> list[tuple]:
    """Certified maxima of sign * c.p for one worker's objectives, on one warm HiGHS model.

    A tall relaxation is solved by row generation: the LP holds a subset of the rows (those
    the share's objectives bound on last time, `_first_rows`), and the rows its optimum
    violates are added until none is (the optimum is then the full LP's).
    The certificate is exact either way: rows outside the LP get multiplier 0.
    """
    if not share:
        return []
    m, n = rel.A.shape
    rows = np.arange(m) if m <= lp.rows_at_once else _first_rows(rel, share, certificates)
    h = load(rel, rows, lp.iterations, lp.scaling)
    # row generation re-solves after adding rows: the simplex goes on from its basis, an
    # interior point method would start over each time
    h.setOptionValue("solver", solver if len(rows) == m else "simplex")
    primal = len(rows) < m and n >= lp.tall_primal_columns
    if primal:
        h.setOptionValue("simplex_strategy", lp.tall_simplex)
    h.setOptionValue("run_crossover", "off")  # (ipm) a point inside is as good a certificate
    cols = np.arange(n, dtype=np.int32)
    check = RowCheck(rel, lp.rows_added) if len(rows) < m else None
    out: list[tuple] = []
    # LP solutions found so far (feasible up to HiGHS's tolerance) and their bases, from the
    # probes on
    points: list[tuple[np.ndarray, tuple | None]] = list(probes or [])
    # the simplex on the whole LP can start from this objective's basis on an earlier box
    keep_basis = (own_bases and certificates is not None and len(rows) == m
                  and solver == "simplex")
    for i, sign, c in share:
        at = _reaching(c, points, rel)
        if at is not None:  # an LP point already lies on the box's bound: the box bound stays
            if keep_basis:  # next time, this objective starts from that point's basis
                out.append((i, sign, np.inf, None, points[at][1], points[at][0]))
            continue
        h.changeColsCost(n, cols, (-c).astype(float))  # maximize c.p as: minimize -c.p
        start = certificates.start(rel, i, sign) if keep_basis and certificates else None
        if start is not None:
            set_basis(h, *start)
        # HiGHS's time limit counts all runs of the object: extend it per solve.
        h.setOptionValue("time_limit", h.getRunTime() + lp.seconds)
        h.run()
        if solver == "ipm" and check is None and not optimal(h):
            # without crossover the interior point method can stop short on a degenerate LP
            # (status unknown) with multipliers far from optimal: the simplex finishes it
            h.setOptionValue("solver", "simplex")
            h.run()
            h.setOptionValue("solver", solver)
        while check is not None:
            sol = h.getSolution()
            if sol.value_valid:
                more = check.violated(np.asarray(sol.col_value), rows)
            else:  # unbounded without the rows left out (an infinite box): take them all
                more, check = np.setdiff1d(np.arange(m), rows), None
            if len(more) == 0:
                break
            add_rows(h, rel, more)
            rows = np.concatenate([rows, more])
            h.run()
        if primal and infeasible(h):
            # the primal simplex ends without the dual ray whose multipliers prove it (bounds
            # that cross): the dual simplex finds it from there
            h.setOptionValue("simplex_strategy", DUAL_SIMPLEX)
            h.run()
            h.setOptionValue("simplex_strategy", lp.tall_simplex)
        if infeasible(h):
            y = _farkas(h, rel, rows)
            if y is not None:  # the relaxation is empty: so is the box (any bound is valid)
                out.append((i, sign, -np.inf, y, None, None))
                break
        # Any multipliers certify a bound, so even a solve stopped by its iteration or time
        # limit gives a valid (if weaker) one: only a missing solution is skipped.
        sol = h.getSolution()
        basis = current_basis(h) if keep_basis else None
        point = None
        if sol.value_valid and h.getInfo().primal_solution_status == 2:  # feasible
            point = np.asarray(sol.col_value)
            points.append((point, basis))
        if sol.dual_valid:
            y = np.zeros(m)
            y[rows] = -np.asarray(sol.row_dual)
            out.append((i, sign, certified_max(rel, c, y, lp.dense_entries), y, basis, point))
    return out




def _farkas(h: Any, rel: LinearRelaxation, rows: np.ndarray) -> np.ndarray | None:
    """Multipliers proving the relaxation empty, from HiGHS's dual ray where it found the LP
    infeasible (None: no ray, or the proof failed in rigorous arithmetic). They prove it as
    any multipliers bound an objective (certified_max): with the objective 0, a bound below
    0 holds for no point. The LP may hold a subset of the rows (row generation): rows left
    out get multiplier 0. Its sign convention is not relied on: both signs are tried."""
    try:
        _, has, ray = h.getDualRay()
    except (AttributeError, RuntimeError, TypeError):
        return None
    ray = np.asarray(ray, dtype=float)
    if not has or len(ray) < len(rows) or not np.all(np.isfinite(ray[:len(rows)])):
        return None
    zero = np.zeros(rel.A.shape[1])
    for sign in (1.0, -1.0):
        y = np.zeros(rel.A.shape[0])
        y[rows] = sign * ray[:len(rows)]
        if certified_max(rel, zero, y) < 0:
            return y
    return None


def _first_rows(rel: LinearRelaxation, share: list,
                certificates: Certificates | None) -> np.ndarray:
    """The rows a tall LP's row generation starts from: those the same objectives' LPs bound
    on last time, over a relaxation of the same family on the box before (the optimum moves
    little, and binds mostly on the same rows, so few rows need adding; docs/decisions/12),
    else evenly spread rows."""
    known = (certificates.binding(rel, [(i, sign) for i, sign, _ in share])
             if certificates is not None else None)
    return known if known is not None else starting_rows(rel)


def _probe_points(rel: LinearRelaxation, tasks: list,
                  lp: LPSettings) -> list[tuple[np.ndarray, tuple | None]]:
    """LP points that attain many of the box's own bounds at once, for every worker's
    `_reaching`: the optima of the sum of the objectives, of its opposite, then of sums with
    random signs (seeded: the same points on every run), while each probe adds an objective
    that no LP needs to solve. One worker's own optima would serve only its share; far from
    the solution (where many unknowns do not move) these serve all, for two to four LPs.
    Only points (and their bases, where an objective they reach starts next time): no bound
    depends on them (see `_reaching`)."""
    if len(tasks) < 4 * lp.probes or rel.A.shape[0] > lp.rows_at_once:
        return []
    h = load(rel, None, lp.iterations, lp.scaling)
    h.setOptionValue("time_limit", lp.seconds)
    n = rel.A.shape[1]
    cols = np.arange(n, dtype=np.int32)
    unsigned = np.array(list({i: sign * c for i, sign, c in tasks}.values()))
    rng = np.random.default_rng(0)
    points: list[tuple[np.ndarray, tuple | None]] = []
    reached = 0
    for k in range(lp.probes):
        signs = (rng.choice([-1.0, 1.0], len(unsigned)) if k >= 2
                 else np.full(len(unsigned), 1.0 if k == 0 else -1.0))
        c = signs @ unsigned
        h.changeColsCost(n, cols, (-c).astype(float))
        h.run()
        sol = h.getSolution()
        if not (sol.value_valid and h.getInfo().primal_solution_status == 2):
            break
        points.append((np.asarray(sol.col_value), current_basis(h)))
        now = sum(_reaching(c_t, points, rel) is not None for _, _, c_t in tasks)
        if now <= reached:
            break
        reached = now
    return points


def _reaching(c: np.ndarray, points: list[tuple[np.ndarray, Any]],
              rel: LinearRelaxation) -> int | None:
    """The first LP point (of (point, basis) pairs) that already attains the box's own bound
    on c.p, or None: then the LP cannot tighten it, and solving it is skipped. (Skipping never
    narrows anything, so it is sound whatever the points are; it saves most LPs of a round
    far from the solution, where many unknowns do not move.)"""
    if not points:
        return None
    box = box_max_up(c, c, rel.lo, rel.hi)
    if not np.isfinite(box):
        return None
    values = np.stack([p for p, _ in points]) @ c
    hits = np.flatnonzero(values >= box - 1e-9 * (1.0 + abs(box)))
    return int(hits[0]) if len(hits) else None



def lp_solutions(rel: LinearRelaxation, objectives: np.ndarray,
                 lp: LPSettings | None = None) -> list[tuple]:
    """lp_bounds' LPs, each objective's result kept: (i, sign, certified max of sign * c.p,
    its multipliers, its optimum in the LP's columns or None), for the LPs that gave
    multipliers (an objective whose box bound an earlier optimum reached has none). For a
    caller that bounds many nearby objectives with a few LPs' multipliers."""
    lp = lp or LPSettings()
    _, _, tasks = box_bounds(rel, objectives)
    workers = max(1, min(lp.workers, len(tasks)))
    share_of = {i: k % workers for k, i in enumerate(dict.fromkeys(t[0] for t in tasks))}
    shares = [[t for t in tasks if share_of[t[0]] == w] for w in range(workers)]
    with ThreadPoolExecutor(workers) as pool:
        results = list(pool.map(lambda share: _solve_share(rel, share, lp), shares))
    return [(i, sign, bound, y, point) for share in results
            for i, sign, bound, y, _, point in share]
