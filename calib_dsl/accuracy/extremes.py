"""Certified points towards the extremes of predictions, for their inner intervals.

Candidates come from two LPs per direction (a prediction's gradient in the parameters): over
the calibration's model linearized at the certified centre (inner/lp.py's, its rows narrowed
a little: its optima lie near the solution set's boundary, readings included), and the
prediction LPs' own optima over the relaxation (outside the solution set, in general). The
first are corrected (accuracy/corrections.py: their LPs solved again with the rows their
checks found violated tightened); what is still unproven is pulled back towards the
certified centre by bisection until certify_point.py proves it, all candidates checked in
one pass per step. Each sign's candidates are found and corrected on a thread of their own
(one sign's checks, in Python, overlap the other's LPs, in HiGHS), whose checks evaluate
their chunks on it alone (the two threads already take both cores).

The second are pulled back the same way only where the linearized model gives no candidate
(no model, or none of its LPs ended optimal): a relaxation optimum's direction is one of the
predictions' gradients, as the linearized LPs' are, and pulled back along a segment from the
centre it stops where the segment leaves the solution set, short of the point the corrected
LP of a nearby direction reaches along the set's boundary. Fewer points can only leave an
inner end where it is or move it inwards; nothing is certified differently.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace

import numpy as np

from calib_dsl.accuracy.batch_lp import path, spread
from calib_dsl.accuracy.corrections import Basis, Candidates, Found, corrected, kept_basis
from calib_dsl.analysis.certify_point import exact_inside
from calib_dsl.analysis.row_screen import RowScreen, screened_holds
from calib_dsl.analysis.row_screen import holds as holds_all
from calib_dsl.inner.bounds import Witness
from calib_dsl.inner.lp import LinearModel
from calib_dsl.ir.program import Program
from calib_dsl.lp.highs import load, optimal
from calib_dsl.relax.chunked import alone
from calib_dsl.relax.layout import independents
from calib_dsl.relax.relaxation import LinearRelaxation
from calib_dsl.settings import LPSettings, Settings


def certified_extremes(prog: Program, box: tuple[np.ndarray, np.ndarray], centre: Witness,
                       directions: np.ndarray, optima: np.ndarray, settings: Settings,
                       screen: RowScreen | None = None) -> list[Found]:
    """Certified points towards the extremes of `directions` (one a row, independents'
    order) within `box` (the independents' bounds): the corrected optima of the model
    linearized at `centre` (the largest's, then the smallest's); only where that model gives
    no candidate, the relaxation's `optima` (with the centre's readings) pulled back towards
    the centre (`screen`: as pulled_back's)."""
    def back(starts: np.ndarray, start_readings: np.ndarray, ends: np.ndarray,
             readings: np.ndarray) -> list[Found | None]:
        return pulled_back(prog, (starts, start_readings), ends, readings,
                           settings.pullback_steps, screen)

    def far() -> list[Found | None]:
        at_centre = np.repeat(centre.readings[None], len(optima), axis=0)
        return back(np.repeat(centre.point[None], len(optima), axis=0), at_centre, optima,
                    at_centre)

    model = _linearized(prog, box, centre, directions, settings)
    start = (centre.point, centre.readings)
    if model is None:
        return [w for w in far() if w is not None]
    if settings.lp.workers <= 1:  # both signs' candidates corrected together
        found = _candidates(model, (1.0, -1.0), settings.lp)
        got = far() if found is None else corrected(prog, found, start, settings, back)
        return [w for w in got if w is not None]
    one = replace(settings, lp=replace(settings.lp, workers=1))  # (a sign's LPs: one model)

    def near(sign: float) -> list[Found | None] | None:  # (None: no candidate)
        with alone():  # (the other sign's thread takes the other core)
            found = _candidates(model, (sign,), one.lp)
            return None if found is None else corrected(prog, found, start, one, back)

    with ThreadPoolExecutor(2) as pool:
        parts = [part.result() for part in [pool.submit(near, 1.0), pool.submit(near, -1.0)]]
    if all(part is None for part in parts):
        parts = [far()]
    return [w for part in parts if part is not None for w in part if w is not None]


Linearized = tuple[LinearModel, np.ndarray, np.ndarray]  # the model, objectives, their path


def _linearized(prog: Program, box: tuple[np.ndarray, np.ndarray], centre: Witness,
                directions: np.ndarray, settings: Settings) -> Linearized | None:
    """The model linearized at `centre` within `box`, the objectives of a spread of the
    `directions` over it and the path their LPs walk (None: no LP)."""
    box = _inside(prog, box)
    free = np.flatnonzero(box[1] > box[0])
    if not len(free) or not len(directions):
        return None
    lm = LinearModel(prog, box, centre.point, free, lp=settings.lp, inner=settings.inner)
    if not lm.finite:
        return None
    # spread apart per unit of each unknown's box, as the LPs see them (the raw gradients
    # mix units: lengths' components swamp angles', and the spread missed their directions)
    picked = directions[spread(directions[:, free] * lm.scale, settings.prediction_linear_lps)]
    objectives = np.zeros((len(picked), lm.n + lm.width))
    objectives[:, :lm.n] = picked[:, free] * lm.scale
    # (each sign walks the directions in a path, each LP from its neighbour's optimum)
    return lm, objectives, path(objectives[:, :lm.n], settings.prediction_path_window)


def _candidates(model: Linearized, signs: tuple[float, ...], lp: LPSettings
                ) -> Candidates | None:
    """The LPs' optima of each sign in `signs` in turn (each sign's walk on a HiGHS model
    of its own, two in threads of their own where lp.workers allows), with their
    objectives and bases."""
    lm, objectives, order = model
    with ThreadPoolExecutor(2 if lp.workers > 1 and len(signs) > 1 else 1) as pool:
        walks = list(pool.map(lambda sign: (sign, _optima(lm.rel, sign * objectives[order],
                                                          lp)), signs))
    found = [(sign * objectives[order[i]], y, basis) for sign, walk in walks
             for i, y, basis in walk]
    if not found:
        return None
    return Candidates(lm, np.array([c for c, _, _ in found]), np.array([y for _, y, _ in found]),
                      [b for _, _, b in found])


def _optima(rel: LinearRelaxation, objectives: np.ndarray, lp: LPSettings
            ) -> list[tuple[int, np.ndarray, Basis | None]]:
    """The optima of max c.x over `rel` for each row c of `objectives` in turn, on one HiGHS
    model, each LP from the last one's basis (a new cost leaves it primal feasible): per
    LP that ended optimal, its row, optimum and basis. Candidates only: nothing here is
    certified."""
    h = load(rel, None, lp.iterations, lp.scaling)
    h.setOptionValue("simplex_strategy", lp.tall_simplex)
    n = objectives.shape[1]
    cols = np.arange(n, dtype=np.int32)
    found = []
    for i, c in enumerate(objectives):
        h.changeColsCost(n, cols, -c.astype(float))
        h.setOptionValue("time_limit", h.getRunTime() + lp.seconds)
        h.run()
        if optimal(h):
            found.append((i, np.asarray(h.getSolution().col_value), kept_basis(h)))
    return found


def pulled_back(prog: Program, starts: Found, candidates: np.ndarray, readings: np.ndarray,
                steps: int, screen: RowScreen | None = None) -> list[Found | None]:
    """For each candidate (independents' order, with its readings), the certified point
    farthest from its certified start (a row of `starts`: points, readings) on the segment
    towards it that bisection finds in `steps` halvings (points and readings moved
    together); None for a candidate with none. `screen` (over the solve's box): each point
    inside it checked only on the rows its second-order bound does not decide
    (analysis/row_screen.py)."""
    if not len(candidates):
        return []
    # (an LP's optimum may stand a tolerance outside the domains: the box is convex, so
    # the segment from the start to its nearest point inside stays inside)
    candidates = np.clip(candidates, *_inside(prog, None))
    good = np.zeros(len(candidates))  # the largest share t of the segment proven
    bad = np.ones(len(candidates))
    t = np.ones(len(candidates))

    def at(i: np.ndarray, share: np.ndarray) -> Found:
        return (_between(starts[0][i], candidates[i], share),
                _between(starts[1][i], readings[i], share))

    for _ in range(steps + 1):
        open_ = np.flatnonzero(bad > good)
        if not len(open_):
            break
        points, values = at(open_, t[open_])
        holds = screened_holds(screen, points, values) if screen is not None else \
            holds_all(prog, points, values)
        good[open_] = np.where(holds, t[open_], good[open_])
        bad[open_] = np.where(holds, bad[open_], t[open_])
        t = np.where(good >= 1.0, 1.0, 0.5 * (good + bad))
    proven = np.flatnonzero(good > 0)
    points, values = at(proven, good[proven])
    out: list[Found | None] = [None] * len(candidates)
    for i, p, r in zip(proven, points, values, strict=True):
        out[int(i)] = (p, r)
    return out


def _inside(prog: Program, box: tuple[np.ndarray, np.ndarray] | None
            ) -> tuple[np.ndarray, np.ndarray]:
    """`box` (the independents' bounds; None: their domains) within the declared domains
    exactly: their floats are rounded outward, and a point on one proves nothing (a domain
    a few ulps wide, with no float inside, keeps its own)."""
    ind = independents(prog)
    lo, hi = prog.slots.lo[ind], prog.slots.hi[ind]
    dlo, dhi = exact_inside(lo, hi)
    some = dlo <= dhi
    dlo, dhi = np.where(some, dlo, lo), np.where(some, dhi, hi)
    if box is None:
        return dlo, dhi
    return np.maximum(box[0], dlo), np.minimum(box[1], dhi)


def _between(start: np.ndarray, ends: np.ndarray, share: np.ndarray) -> np.ndarray:
    """start + share (end - start) for each row of `ends` (and of `start`, where it has as
    many), kept within the two (rounded, a share of 1 can land an ulp beyond the end:
    outside the domains the check requires)."""
    moved = start + share[:, None] * (ends - start)
    return np.clip(moved, np.minimum(start, ends), np.maximum(start, ends))
