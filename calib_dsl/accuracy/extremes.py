"""Certified points towards the extremes of predictions, for their inner intervals.

Candidates come from two LPs per direction (a prediction's gradient in the parameters): over
the calibration's model linearized at the certified centre (inner_lp.py's, its rows narrowed
a little: its optima lie near the solution set's boundary, readings included), and the
prediction LPs' own optima over the relaxation (outside the solution set, in general). Each
is pulled back towards the certified centre by bisection until certify_point.py proves it,
all candidates checked in one pass per step.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

from calib_dsl.accuracy.batch_lp import path, spread
from calib_dsl.analysis.certify_point import check_points
from calib_dsl.analysis.existence import prove_point
from calib_dsl.analysis.row_screen import RowScreen, screened_holds
from calib_dsl.inner.bounds import Witness
from calib_dsl.inner.lp import LinearModel
from calib_dsl.ir.program import Program
from calib_dsl.lp.highs import load, optimal
from calib_dsl.relax.layout import independents
from calib_dsl.relax.relaxation import LinearRelaxation
from calib_dsl.settings import LPSettings, Settings


def linearized_optima(prog: Program, box: tuple[np.ndarray, np.ndarray], centre: Witness,
                      directions: np.ndarray, settings: Settings
                      ) -> tuple[np.ndarray, np.ndarray]:
    """The optima (points, readings) of the largest and smallest of each of a spread of the
    `directions` (one a row, independents' order) over the model linearized at `centre`
    within `box` (the independents' bounds)."""
    free = np.flatnonzero(box[1] > box[0])
    n = len(centre.point)
    none = (np.zeros((0, n)), np.zeros((0, len(centre.readings))))
    if not len(free) or not len(directions):
        return none
    lm = LinearModel(prog, box, centre.point, free)
    if not lm.finite:
        return none
    picked = directions[spread(directions, settings.prediction_linear_lps)]
    objectives = picked[:, free] * lm.scale
    # (each sign walks the directions in a path, each LP from its neighbour's optimum)
    order = path(objectives, settings.prediction_path_window)
    with ThreadPoolExecutor(2 if settings.lp.workers > 1 else 1) as pool:
        walks = list(pool.map(lambda sign: _optima(lm.rel, sign * objectives[order],
                                                   settings.lp), (1.0, -1.0)))
    found = [lm.point(y) for walk in walks for y in walk]
    if not found:
        return none
    return np.array([p for p, _ in found]), np.array([r for _, r in found])


def _optima(rel: LinearRelaxation, objectives: np.ndarray, lp: LPSettings
            ) -> list[np.ndarray]:
    """The optima of max c.x over `rel` for each row c of `objectives` in turn, on one HiGHS
    model, each LP from the last one's basis (a new cost leaves it primal feasible); an LP
    that did not end optimal gives none. Candidates only: nothing here is certified."""
    h = load(rel, None, lp.iterations, lp.scaling)
    h.setOptionValue("simplex_strategy", lp.tall_simplex)
    n = objectives.shape[1]
    cols = np.arange(n, dtype=np.int32)
    found = []
    for c in objectives:
        h.changeColsCost(n, cols, -c.astype(float))
        h.setOptionValue("time_limit", h.getRunTime() + lp.seconds)
        h.run()
        if optimal(h):
            found.append(np.asarray(h.getSolution().col_value))
    return found


def pulled_back(prog: Program, centre: Witness, candidates: np.ndarray,
                readings: np.ndarray, steps: int, screen: RowScreen | None = None
                ) -> list[tuple[np.ndarray, np.ndarray]]:
    """For each candidate (independents' order, with its readings), the certified point
    farthest from the certified `centre` on the segment towards it that bisection finds in
    `steps` halvings (points and readings moved together); candidates with none left out.
    `screen` (over a box holding the candidates and the centre): each point checked only on
    the rows its second-order bound does not prove (analysis/row_screen.py)."""
    if not len(candidates):
        return []
    ind = independents(prog)
    # (an LP's optimum may stand a tolerance outside the domains: the box is convex, so
    # the segment from the centre to its nearest point inside stays inside)
    candidates = np.clip(candidates, prog.slots.lo[ind], prog.slots.hi[ind])
    good = np.zeros(len(candidates))  # the largest share t of the segment proven
    bad = np.ones(len(candidates))
    t = np.ones(len(candidates))

    def at(i: np.ndarray, share: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return (_between(centre.point, candidates[i], share),
                _between(centre.readings, readings[i], share))

    for _ in range(steps + 1):
        open_ = np.flatnonzero(bad > good)
        if not len(open_):
            break
        points, values = at(open_, t[open_])
        holds = screened_holds(screen, points, values) if screen is not None else \
            _holds(prog, points, values)
        good[open_] = np.where(holds, t[open_], good[open_])
        bad[open_] = np.where(holds, bad[open_], t[open_])
        t = np.where(good >= 1.0, 1.0, 0.5 * (good + bad))
    proven = np.flatnonzero(good > 0)
    points, values = at(proven, good[proven])
    return list(zip(points, values, strict=True))


def _holds(prog: Program, points: np.ndarray, values: np.ndarray) -> np.ndarray:
    checks = check_points(prog, points, values)
    return np.array([c.holds or prove_point(prog, p, r, c)
                     for p, r, c in zip(points, values, checks, strict=True)])


def _between(start: np.ndarray, ends: np.ndarray, share: np.ndarray) -> np.ndarray:
    """start + share (end - start) for each row of `ends`, kept within the two (rounded, a
    share of 1 can land an ulp beyond the end: outside the domains the check requires)."""
    moved = start + share[:, None] * (ends - start)
    return np.clip(moved, np.minimum(start, ends), np.maximum(start, ends))
