"""Certified inner bounds: for each unknown, an interval [a, b] inside the hull of the solution
set, so that outer/inner widths say how much of an enclosure is real.

a and b are coordinates of parameter vectors that certify_point.py proves to satisfy every
constraint (interval evaluation at the point, outward rounding: floating point is never
trusted). The candidates are the extremes of each unknown over the model linearized at a
certified centre (one LP per end, the same LP re-solved with another objective); where the
linearization's remainder makes a candidate fail, the rows it violates are tightened by what
the check measured and the LP is solved again, and as a last resort the candidate is pulled
back towards the centre. An end that this left well short of its LP's optimum is sought
again over the model linearized at its point. Every certified point adds to every unknown's
interval.
"""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace

import numpy as np

from calib_dsl.analysis.certify_point import PointCheck, check_point, exact_inside
from calib_dsl.analysis.chebyshev import chebyshev
from calib_dsl.analysis.existence import prove_point
from calib_dsl.analysis.lsq import linearized
from calib_dsl.analysis.readings import Readings
from calib_dsl.ir.program import Program
from calib_dsl.lp.highs import RowCheck, add_rows, load, optimal
from calib_dsl.relax.layout import independents
from calib_dsl.relax.relaxation import LinearRelaxation, Rows
from calib_dsl.settings import DEFAULT

# Each row aims inside this share of its bound: room for the rounding and for the remainder of
# the linearization at the LP's optimum (measured on the RX90: 1e-6 to 1e-5 of the bounds).
AIM = 1.0 - 1e-5
CORRECTIONS = 6  # re-solves of one end's LP with the rows the check found violated tightened
ESCALATE = 4.0  # how much more a row that fails again is tightened
OVERSHOOT = 2.0  # a violated row is tightened by this many times its measured excess
# An end that a certified point reaches to within this share of the outer width gets no LP of
# its own (an earlier end's LP often puts the other unknowns at their bounds: on Test A the 19
# parameters known to +-1e-5)
REACHED = 1e-4
COMPUTED_AIM = 1e-3  # the first tightening of a failed row between two computed values
PULLBACKS = 10  # halvings of the step from the centre when the corrections did not succeed
# An end whose certified point falls short of its LP's optimum by more than this share of the
# unknown's width (the remainder made the corrections pull it in) is sought again over the
# model linearized at that point, where the remainder is small (while the LP holds all its
# rows at once). On the UR10's every 15th row 17 of 46 ends, each reaching 1-4 % of its width
# further (outer/inner median 1.092 -> 1.053)
REFINE = 1e-2
# The centre's fit stops once its linearized model predicts the largest residual to within
# this share: the centre needs a margin inside every bound, not the best fit (on Test A the
# second and third steps lowered it by 2e-6, 0.07 s)
SETTLE = 1e-3


@dataclass(frozen=True)
class Witness:
    """A certified point: the unknowns (independents' order) and the joint readings
    (certify_point.reading_slots order) at which every constraint was proven to hold (but a
    row comparing two computed values, proven by existence.py: its own readings then lie
    between two vectors, not at these values)."""

    point: np.ndarray
    readings: np.ndarray


@dataclass(frozen=True)
class Inner:
    """Per unknown (independents' order), the smallest and largest value it takes at a
    certified point (nan where none was certified), and the points that give them."""

    names: tuple[str, ...]
    lo: np.ndarray
    hi: np.ndarray
    witnesses: tuple[Witness, ...]  # the first is the centre
    lo_at: np.ndarray  # per unknown, the witness giving lo (-1: none)
    hi_at: np.ndarray
    seconds: float

    @property
    def consistent(self) -> bool:
        """The data are proven consistent: some parameter vector satisfies every constraint."""
        return bool(self.witnesses)

    @property
    def points(self) -> int:
        return len(self.witnesses)


def inner_bounds(prog: Program, lo: np.ndarray, hi: np.ndarray) -> Inner:
    """Certified inner intervals of the unknowns, searched within the outer box [lo, hi] (over
    the program's slots: the solve's result)."""
    start = time.perf_counter()
    ind = independents(prog)
    names = tuple(prog.slots.names[i] for i in ind)
    # within the result, and within the declared domains exactly (their floats are rounded
    # outward; a domain a few ulps wide keeps its float bounds and certifies nothing)
    dlo, dhi = exact_inside(prog.slots.lo[ind], prog.slots.hi[ind])
    some = dlo <= dhi
    box = (np.where(some, np.maximum(lo[ind], dlo), lo[ind]).astype(float),
           np.where(some, np.minimum(hi[ind], dhi), hi[ind]).astype(float))
    found = _Points(len(ind))
    centre, ends = _centre(prog, box)
    if centre is not None:
        found.add(centre)
        _extremes(prog, box, centre.point, found, ends)
    return Inner(names, found.lo, found.hi, tuple(found.all), found.lo_at, found.hi_at,
                 time.perf_counter() - start)


class _Points:
    """The certified points seen so far, and per unknown the range they span."""

    def __init__(self, n: int) -> None:
        self.lo, self.hi = np.full(n, np.nan), np.full(n, np.nan)
        self.lo_at, self.hi_at = np.full(n, -1), np.full(n, -1)
        self.all: list[Witness] = []

    def add(self, w: Witness) -> None:
        k = len(self.all)
        self.all.append(w)
        lower, higher = ~(w.point >= self.lo), ~(w.point <= self.hi)  # nan: none yet
        self.lo[lower], self.lo_at[lower] = w.point[lower], k
        self.hi[higher], self.hi_at[higher] = w.point[higher], k


@dataclass(frozen=True)
class _Ends:
    """The model linearized at the box's middle and its LP optima at the ends of the free
    unknowns ((j, sign): step): the ends' first candidates where the centre is their mean."""

    lp: _LinearModel
    steps: dict[tuple[int, float], np.ndarray]


def _centre(prog: Program, box: tuple[np.ndarray, np.ndarray]
            ) -> tuple[Witness | None, _Ends | None]:
    """A certified point near the middle of the box (the middle itself, else the point with
    the smallest largest residual in units of each row's bound, else the mean of the ends of
    the model linearized at the middle): the LPs' starting point; and those ends, where
    they were computed."""
    lo, hi = box
    mid = np.where(np.isfinite(lo) & np.isfinite(hi), 0.5 * (lo + hi), np.clip(0.0, lo, hi))
    mid = np.clip(mid, lo, hi)
    middles = Readings(prog).middles()
    if prove_point(prog, mid, middles):  # a tight box's middle often is a solution
        return Witness(mid, middles), None
    try:
        with np.errstate(all="ignore"):
            p, need = chebyshev(prog, normalized=True, start=mid, box=box, target=1.0,
                                settle=SETTLE)
        if need < 1.0 and np.all(np.isfinite(p)) and prove_point(prog, p, middles):
            return Witness(p, middles), None
    except (ValueError, np.linalg.LinAlgError):
        pass
    return _mean_of_ends(prog, box, mid)


def _mean_of_ends(prog: Program, box: tuple[np.ndarray, np.ndarray],
                  mid: np.ndarray) -> tuple[Witness | None, _Ends | None]:
    """The mean of the linearized model's ends, a point inside it: where the Chebyshev fit
    cannot run (an inequality's bound is infinite, so it has no units) or does not reach
    inside every bound (the joint readings at their middles)."""
    free = np.flatnonzero(box[1] > box[0])
    if not len(free):
        return None, None
    lp = _LinearModel(prog, box, mid, free)
    if not lp.finite:
        return None, None
    steps = lp.extremes([(j, sign) for j in range(len(free)) for sign in (-1.0, 1.0)])
    if not steps:
        return None, None
    point, readings = lp.point(np.mean(list(steps.values()), axis=0))
    if not prove_point(prog, point, readings):
        return None, None
    return Witness(point, readings), _Ends(lp, steps)


def _extremes(prog: Program, box: tuple[np.ndarray, np.ndarray], centre: np.ndarray,
              found: _Points, start: _Ends | None) -> None:
    """Both ends of every unknown that can move, over the model linearized at the centre (or
    at the middle, where the centre is the mean of that model's ends: their LPs are not
    solved twice); then those that fell well short, over the model linearized at their own
    points (where the LP holds all its rows: above, each would be a cold LP generating its
    rows, 0.33 s an end on all 1495 UR10 rows, 28 ends for a median outer/inner of 1.178
    against 1.225)."""
    free = np.flatnonzero(box[1] > box[0])
    if not len(free):
        return
    lp = start.lp if start is not None else _LinearModel(prog, box, centre, free)
    if not lp.finite:  # the model cannot be linearized there (an infinite derivative)
        return
    solvers = lp.solvers(DEFAULT.lp_workers)
    with ThreadPoolExecutor(len(solvers)) as pool:
        short = _waves(prog, lp, solvers, pool, found, start)
        if lp.rows <= DEFAULT.rows_at_once:
            for w in pool.map(lambda end: _refined(prog, box, free, *end), short):
                if w is not None:
                    found.add(w)


def _waves(prog: Program, lp: _LinearModel, solvers: list[_Solver], pool: ThreadPoolExecutor,
           found: _Points, start: _Ends | None) -> list[tuple[int, float, Witness]]:
    """The ends not yet reached, in waves of one end per HiGHS model and thread (HiGHS
    releases the GIL, so one end's LP runs while another's point is checked); a wave's
    points count before the next wave is chosen, in the same order on every run. Returns the
    ends (j, sign, point) whose point fell short of their LP's optimum by REFINE."""
    lo, hi = lp.box
    ends = [(j, int(k), sign) for j, k in enumerate(lp.free) for sign in (-1.0, 1.0)]

    def unreached(k: int, sign: float) -> bool:
        reached, bound = (found.hi[k], hi[k]) if sign > 0 else (found.lo[k], lo[k])
        return not abs(bound - reached) <= REACHED * (hi[k] - lo[k])

    def run(w: int, end: tuple[int, int, float]) -> tuple[Witness | None, float]:
        j, _, sign = end
        first = None if start is None else start.steps.get((j, sign))
        return _end(prog, lp, solvers[w], j, sign, first)

    short = []
    while ends:
        wave: list[tuple[int, int, float]] = []
        while ends and len(wave) < len(solvers):
            end = ends.pop(0)
            if unreached(end[1], end[2]):
                wave.append(end)
        for (j, k, sign), (w, promised) in zip(wave, pool.map(run, range(len(wave)), wave),
                                               strict=True):
            if w is not None:
                found.add(w)
                if sign * (promised - (w.point[k] - lp.centre[k]) / lp.scale[j]) > REFINE:
                    short.append((j, sign, w))
    return short


def _refined(prog: Program, box: tuple[np.ndarray, np.ndarray], free: np.ndarray, j: int,
             sign: float, w: Witness) -> Witness | None:
    """The end again, over the model linearized at its certified point w: near the end, the
    linearization's remainder that held it back is small."""
    lp = _LinearModel(prog, box, w.point, free)
    return _end(prog, lp, lp.solver, j, sign)[0] if lp.finite else None


def _end(prog: Program, lp: _LinearModel, solver: _Solver, j: int, sign: float,
         first: np.ndarray | None = None) -> tuple[Witness | None, float]:
    """A certified point far along the free unknown j in the direction `sign`, from the LPs
    of `solver` (one of lp's models; `first`: the LP's optimum with no row tightened, when
    already known); and that optimum's step along j (in units of its width, nan if none):
    how far the linearized model promised."""
    tighten = np.zeros(lp.rows)
    step = np.zeros(0)
    promised = np.nan
    for k in range(CORRECTIONS):
        y = first if k == 0 and first is not None else solver.extreme(j, sign, tighten)
        if y is None:  # tightened beyond what the LP can meet
            break
        step = y
        promised = float(y[j]) if k == 0 else promised
        point, readings = lp.point(step)
        check = check_point(prog, point, readings)
        if check.holds or prove_point(prog, point, readings, check):
            return Witness(point, readings), promised
        excess, computed = lp.excess(check)
        # a row that fails again was not binding in the LP: its remainder exceeds what it
        # was tightened by, so aim further inside, fourfold
        again = (excess > 0) & (tighten > 0)
        tighten += OVERSHOOT * excess
        tighten[again] = np.maximum(tighten[again], ESCALATE * (tighten[again]
                                                                - OVERSHOOT * excess[again]))
        # a row between two computed values fails by its remainder, not by its (whole)
        # difference: aim further inside, doubling
        tighten[computed] = np.maximum(2.0 * tighten[computed], COMPUTED_AIM)
    for _ in range(PULLBACKS if len(step) else 0):
        step = 0.5 * step
        point, readings = lp.point(step)
        if prove_point(prog, point, readings):
            return Witness(point, readings), promised
    return None, promised


class _LinearModel:
    """The rows linearized at the centre: each row's residual r + A y + B z (in units of the
    row's bound; y the free unknowns' step in units of their widths, z the readings' errors
    in units of their bounds) within its interval, narrowed by 1 - AIM and `tighten` at each
    finite end, the variables within the box; solved by HiGHS models (_Solver) whose
    objective and row bounds change from one end to the next."""

    def __init__(self, prog: Program, box: tuple[np.ndarray, np.ndarray], centre: np.ndarray,
                 free: np.ndarray) -> None:
        lo, hi = box
        lin = linearized(prog, centre)
        self.centre, self.free, self.box = centre, free, box
        self.scale = np.where(np.isfinite(hi - lo), hi - lo, 1.0)[free]
        with np.errstate(all="ignore"):
            dense = lin.jac[:, free] * self.scale
            # a row's unit: its bound, or for an inequality the size of its terms
            size = np.fmax(np.abs(np.where(np.isfinite(lin.r_lo), lin.r_lo, lin.r_hi)),
                           np.abs(dense).max(axis=1, initial=0.0))
            unit = np.where(np.isfinite(lin.half) & (lin.half > 0), lin.half, size)
            unit = np.maximum(np.where(np.isfinite(unit), unit, 1.0), 1e-300)
            self.lower, self.upper = -lin.r_hi / unit, -lin.r_lo / unit  # A y within these
            dense = dense / unit[:, None]
        self.slots, self.unit, self.nslots = lin.slots, unit, len(prog.slots.names)
        self.rows, self.n = len(unit), len(free)
        self.finite = bool(np.all(np.isfinite(dense))
                           and not np.any(np.isnan(self.lower) | np.isnan(self.upper)))
        if not self.finite:
            return
        self.readings = Readings(prog)
        # the readings as LP columns (each may take its own value within its interval), up
        # to inner_reading_columns; beyond, they stay at their middles (a narrower inner
        # interval, as certain: the LP would be tens of thousands of columns wide)
        free_readings = len(self.readings.mid) <= DEFAULT.inner_reading_columns
        rows, cols, vals = self.readings.entries(lin) if free_readings else \
            (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0))
        self.width = len(self.readings.mid) if free_readings else 0
        A = Rows.join(dense, rows, cols, vals / unit[rows], self.width)
        ylo, yhi = (lo[free] - centre[free]) / self.scale, (hi[free] - centre[free]) / self.scale
        zlo, zhi = self.readings.bounds() if free_readings else (np.zeros(0), np.zeros(0))
        b_lo, b = self.bounds(np.zeros(self.rows))
        self.rel = LinearRelaxation(A, b, np.r_[ylo, zlo], np.r_[yhi, zhi], b_lo=b_lo)
        self.solver = _Solver(self)

    def bounds(self, tighten: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The rows' bounds narrowed by 1 - AIM and `tighten` (an infinite end stays)."""
        inward = (1.0 - AIM) + tighten
        return self.lower + inward, self.upper - inward

    def solvers(self, count: int) -> list[_Solver]:
        """`count` HiGHS models of this LP (at least one), the first the model's own."""
        return [self.solver] + [_Solver(self) for _ in range(max(1, count) - 1)]

    def extremes(self, ends: list[tuple[int, float]]) -> dict[tuple[int, float], np.ndarray]:
        """The optima of these ends with no row tightened (those the LP found), shared among
        lp_workers threads, each with its own HiGHS model (HiGHS releases the GIL)."""
        workers = max(1, min(DEFAULT.lp_workers, len(ends)))
        solvers = self.solvers(workers)
        untightened = np.zeros(self.rows)

        def share(w: int) -> list[tuple[tuple[int, float], np.ndarray | None]]:
            return [(e, solvers[w].extreme(*e, untightened)) for e in ends[w::workers]]

        if workers == 1:
            found = share(0)
        else:
            with ThreadPoolExecutor(workers) as pool:
                found = [x for part in pool.map(share, range(workers)) for x in part]
        return {e: y for e, y in found if y is not None}

    def point(self, step: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The unknowns and the readings at `step` from the centre (kept in their bounds: a
        step to an edge may round out of it)."""
        p = self.centre.copy()
        p[self.free] = self.centre[self.free] + self.scale * step[:self.n]
        if not self.width:
            return np.clip(p, *self.box), self.readings.middles()
        return np.clip(p, *self.box), self.readings.values(step[self.n:])

    def excess(self, check: PointCheck) -> tuple[np.ndarray, np.ndarray]:
        """How far each row stuck out at a failed point, in units of its bound, and which
        failed rows compare two computed values."""
        assert check.computed is not None and check.ok is not None
        plain = ~check.computed
        out = np.zeros(self.nslots)
        np.maximum.at(out, check.slots[plain],
                      np.where(np.isfinite(check.excess[plain]), check.excess[plain], 0.0))
        failed = np.zeros(self.nslots, dtype=bool)
        failed[check.slots[check.computed & ~check.ok]] = True
        return out[self.slots] / self.unit, failed[self.slots]


class _Solver:
    """A HiGHS model of a _LinearModel's LP: its rows' bounds as last tightened, and the rows
    it holds (a tall model holds some, and those an optimum violates are added: row
    generation, each LP small, the optimum the whole model's). One per thread."""

    def __init__(self, model: _LinearModel) -> None:
        self.model, self.rel = model, model.rel
        tall = model.rows > DEFAULT.rows_at_once
        self.in_lp = (np.unique(np.linspace(0, model.rows - 1, 8 * model.n).astype(np.int64))
                      if tall else np.arange(model.rows))  # (a few rows per unknown)
        self.h = load(self.rel, self.in_lp if tall else None)
        self.tightened = np.zeros(model.rows)

    def extreme(self, j: int, sign: float, tighten: np.ndarray) -> np.ndarray | None:
        """The LP's optimum (y, z) for the largest (sign > 0) or smallest free unknown j."""
        m = self.model
        h, cols = self.h, m.n + m.width
        cost = np.zeros(cols)
        cost[j] = -sign  # HiGHS minimizes
        h.changeColsCost(cols, np.arange(cols, dtype=np.int32), cost)
        if np.any(tighten != self.tightened):
            b_lo, b = m.bounds(tighten)
            self.rel = replace(self.rel, b=b, b_lo=b_lo)
            inf = 1e300  # HiGHS's infinity: anything beyond 1e20
            at = self.in_lp
            h.changeRowsBounds(len(at), np.arange(len(at), dtype=np.int32),
                               np.maximum(b_lo[at], -inf), np.minimum(b[at], inf))
            self.tightened = tighten.copy()
        h.run()
        check = RowCheck(self.rel) if len(self.in_lp) < m.rows else None
        while check is not None and optimal(h) and len(self.in_lp) < m.rows:
            more = check.violated(np.asarray(h.getSolution().col_value), self.in_lp)
            if not len(more):
                break
            add_rows(h, self.rel, more)
            self.in_lp = np.concatenate([self.in_lp, more])
            h.run()
        if not optimal(h):
            return None
        return np.array(h.getSolution().col_value)
