"""Certified points towards the extremes of predictions, for their inner intervals.

Candidates come from two LPs per direction (a prediction's gradient in the parameters): over
the calibration's model linearized at the certified centre (inner_lp.py's, its rows narrowed
a little: its optima lie near the solution set's boundary, readings included), and the
prediction LPs' own optima over the relaxation (outside the solution set, in general). Each
is pulled back towards the certified centre by bisection until certify_point.py proves it,
all candidates checked in one pass per step.
"""

from __future__ import annotations

import numpy as np

from calib_dsl.accuracy.batch_lp import spread
from calib_dsl.analysis.certify_point import check_points
from calib_dsl.analysis.existence import prove_point
from calib_dsl.inner.bounds import Witness
from calib_dsl.inner.lp import LinearModel
from calib_dsl.ir.program import Program
from calib_dsl.lp.bounds import lp_solutions
from calib_dsl.relax.layout import independents
from calib_dsl.settings import Settings


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
    found = [lm.point(y) for *_, y in lp_solutions(lm.rel, picked[:, free] * lm.scale,
                                                   settings.lp)
             if y is not None]
    if not found:
        return none
    return np.array([p for p, _ in found]), np.array([r for _, r in found])


def pulled_back(prog: Program, centre: Witness, candidates: np.ndarray,
                readings: np.ndarray, steps: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """For each candidate (independents' order, with its readings), the certified point
    farthest from the certified `centre` on the segment towards it that bisection finds in
    `steps` halvings (points and readings moved together); candidates with none left out."""
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
        checks = check_points(prog, points, values)
        holds = np.array([c.holds or prove_point(prog, p, r, c)
                          for p, r, c in zip(points, values, checks, strict=True)])
        good[open_] = np.where(holds, t[open_], good[open_])
        bad[open_] = np.where(holds, bad[open_], t[open_])
        t = np.where(good >= 1.0, 1.0, 0.5 * (good + bad))
    proven = np.flatnonzero(good > 0)
    points, values = at(proven, good[proven])
    return list(zip(points, values, strict=True))


def _between(start: np.ndarray, ends: np.ndarray, share: np.ndarray) -> np.ndarray:
    """start + share (end - start) for each row of `ends`, kept within the two (rounded, a
    share of 1 can land an ulp beyond the end: outside the domains the check requires)."""
    moved = start + share[:, None] * (ends - start)
    return np.clip(moved, np.minimum(start, ends), np.maximum(start, ends))
