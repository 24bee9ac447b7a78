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
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, replace

import numpy as np

from calib_dsl.analysis.certify_point import PointCheck, check_point, check_points, exact_inside
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
# A failed LP optimum is pulled back towards the centre only where that costs the end at
# most this share of the unknown's width; else its LP is re-solved with the failed rows
# tightened, which loses less (rx90_full.cal: worst outer/inner 1.0395, against 1.0507 when
# a pull-back may cost up to REFINE)
PULLED = 1e-3
# Ends per wave: their LPs shared among the threads, their points checked in one pass (eight
# points cost about three checks of one on the RX90); a wider wave runs LPs for ends that an
# earlier wave's points would have reached
WAVE = 16
CORRECTIONS = 6  # re-solves of one end's LP with the rows the check found violated tightened
ESCALATE = 4.0  # how much more a row that fails again is tightened
OVERSHOOT = 2.0  # a violated row is tightened by this many times its measured excess
# An end that a certified point reaches to within this share of the outer width gets no LP of
# its own (an earlier end's LP often puts the other unknowns at their bounds: on Test A the 19
# parameters known to +-1e-5). The ends an LP finds fall about as short (Test A: 1e-3 of the
# width), so a tighter share buys LPs, not width
REACHED = 1e-3
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
    _search(prog, box, found)
    return Inner(names, found.lo, found.hi, tuple(found.all), found.lo_at, found.hi_at,
                 time.perf_counter() - start)


class _Points:
    """The certified points seen so far, and per unknown the range they span; `centre`, the
    point that failed candidates are pulled back towards (None until one is certified)."""

    def __init__(self, n: int) -> None:
        self.lo, self.hi = np.full(n, np.nan), np.full(n, np.nan)
        self.lo_at, self.hi_at = np.full(n, -1), np.full(n, -1)
        self.all: list[Witness] = []
        self.centre: Witness | None = None
        self._centre_check: PointCheck | None = None

    def add(self, w: Witness) -> None:
        k = len(self.all)
        self.all.append(w)
        lower, higher = ~(w.point >= self.lo), ~(w.point <= self.hi)  # nan: none yet
        self.lo[lower], self.lo_at[lower] = w.point[lower], k
        self.hi[higher], self.hi_at[higher] = w.point[higher], k

    def add_centre(self, w: Witness, check: PointCheck | None = None) -> None:
        self.centre, self._centre_check = w, check
        self.add(w)

    def centre_check(self, prog: Program) -> PointCheck:
        """The centre's check: each row's room to its bounds there."""
        assert self.centre is not None
        if self._centre_check is None:
            self._centre_check = check_point(prog, self.centre.point, self.centre.readings)
        return self._centre_check


def _search(prog: Program, box: tuple[np.ndarray, np.ndarray], found: _Points) -> None:
    """The certified points: the box's middle if it is one; then both ends of every unknown
    that can move, over the model linearized at the middle (at the Chebyshev fit where it
    cannot be linearized there)."""
    lo, hi = box
    mid = np.where(np.isfinite(lo) & np.isfinite(hi), 0.5 * (lo + hi), np.clip(0.0, lo, hi))
    mid = np.clip(mid, lo, hi)
    middles = Readings(prog).middles()
    if prove_point(prog, mid, middles):  # a tight box's middle often is a solution
        found.add_centre(Witness(mid, middles))
    free = np.flatnonzero(hi > lo)
    if not len(free):
        return
    lp = _LinearModel(prog, box, mid, free)
    if not lp.finite:  # an infinite derivative at the middle
        if found.centre is None and (centre := _fit(prog, box, mid)) is not None:
            found.add_centre(centre)
        if found.centre is None:
            return
        lp = _LinearModel(prog, box, found.centre.point, free)
        if not lp.finite:
            return
    _extremes(prog, box, lp, found)


def _fit(prog: Program, box: tuple[np.ndarray, np.ndarray], mid: np.ndarray) -> Witness | None:
    """The point with the smallest largest residual (in units of each row's bound, the
    readings at their middles), from the middle, if it is certified: a centre where the
    mean of the first wave's ends is not one."""
    middles = Readings(prog).middles()
    try:
        with np.errstate(all="ignore"):
            p, need = chebyshev(prog, normalized=True, start=mid, box=box, target=1.0,
                                settle=SETTLE)
    except (ValueError, np.linalg.LinAlgError):
        return None
    if need < 1.0 and np.all(np.isfinite(p)) and prove_point(prog, p, middles):
        return Witness(p, middles)
    return None


def _extremes(prog: Program, box: tuple[np.ndarray, np.ndarray], lp: _LinearModel,
              found: _Points) -> None:
    """Both ends of every unknown that can move, over the linearized model `lp`; then
    those that fell well short, over the model linearized at their own points (where the LP
    holds all its rows: above, each would be a cold LP generating its rows, 0.33 s an end on
    all 1495 UR10 rows, 28 ends for a median outer/inner of 1.178 against 1.225)."""
    solvers = lp.solvers(DEFAULT.lp_workers)
    with ThreadPoolExecutor(len(solvers)) as pool:
        short = _waves(prog, lp, solvers, pool, found)
        if lp.rows <= DEFAULT.rows_at_once:
            for w in pool.map(lambda end: _refined(prog, box, lp.free, *end),
                              short):
                if w is not None:
                    found.add(w)


def _waves(prog: Program, lp: _LinearModel, solvers: list[_Solver], pool: ThreadPoolExecutor,
           found: _Points) -> list[tuple[int, float, Witness]]:
    """The ends not yet reached, in waves of WAVE. The HiGHS models solve a wave's LPs in
    their threads (HiGHS releases the GIL) while this thread checks the wave before, so a
    wave is chosen before the points of the one just solved count: in the same order on
    every run. Returns the ends (j, sign, point) whose point fell short of their LP's
    optimum by REFINE."""
    lo, hi = lp.box
    ends = [(j, int(k), sign) for j, k in enumerate(lp.free) for sign in (-1.0, 1.0)]
    share, untightened = len(solvers), np.zeros(lp.rows)

    def unreached(k: int, sign: float) -> bool:
        reached, bound = (found.hi[k], hi[k]) if sign > 0 else (found.lo[k], lo[k])
        return not abs(bound - reached) <= REACHED * (hi[k] - lo[k])

    def optima(wave: list[tuple[int, int, float]], w: int) -> list[np.ndarray | None]:
        return [solvers[w].extreme(j, sign, untightened) for j, _, sign in wave[w::share]]

    def launch() -> tuple[list[tuple[int, int, float]], list[Future]]:
        wave: list[tuple[int, int, float]] = []
        while ends and len(wave) < WAVE:
            end = ends.pop(0)
            if unreached(end[1], end[2]):
                wave.append(end)
        return wave, [pool.submit(optima, wave, w) for w in range(min(share, len(wave)))]

    def gather(running: list[Future]) -> list[np.ndarray | None]:
        ys: list[np.ndarray | None] = [None] * sum(len(r.result()) for r in running)
        for w, r in enumerate(running):
            ys[w::share] = r.result()
        return ys

    short = []
    wave, running = launch()
    ys = gather(running)
    while wave:
        after, running = launch()
        done, failed = _checked(prog, lp, wave, ys, found)
        ys_after = gather(running)
        for i, w in _corrected(prog, lp, solvers, pool, wave, ys, failed, found.centre):
            done[i] = w
        for (j, k, sign), w, y in zip(wave, done, ys, strict=True):
            if w is not None:
                found.add(w)
                assert y is not None
                if sign * (y[j] - (w.point[k] - lp.centre[k]) / lp.scale[j]) > REFINE:
                    short.append((j, sign, w))
        wave, ys = after, ys_after
    return short


def _checked(prog: Program, lp: _LinearModel, wave: list[tuple[int, int, float]],
             ys: list[np.ndarray | None], found: _Points
             ) -> tuple[list[Witness | None], dict[int, PointCheck]]:
    """The wave's LP optima checked in one pass (with their mean, a centre, while there is
    none); those that fail on plain rows pulled back towards the centre by what the check
    measured (_pull_back) and checked in one more. Returns the certified points (None where
    none yet) and the failed optima's checks."""
    done: list[Witness | None] = [None] * len(wave)
    failed: dict[int, PointCheck] = {}
    at = {i: lp.point(y) for i, y in enumerate(ys) if y is not None}
    if found.centre is None and at:
        at[-1] = lp.point(np.mean([y for y in ys if y is not None], axis=0))
    for pulled in (False, True):
        if not at:
            break
        order = sorted(at)
        checks = check_points(prog, np.array([at[i][0] for i in order]),
                              np.array([at[i][1] for i in order]))
        here, at = at, {}
        for i, check in zip(order, checks, strict=True):
            point, readings = here[i]
            if not (check.holds or prove_point(prog, point, readings, check)):
                if not pulled and i >= 0:
                    failed[i] = check
                continue
            if i < 0:
                found.add_centre(Witness(point, readings), check)
            else:
                done[i] = Witness(point, readings)
        if not pulled and found.centre is None:
            if (centre := _fit(prog, lp.box, lp.centre)) is None:
                break
            found.add_centre(centre)
        for i in [] if pulled else sorted(failed):
            assert found.centre is not None
            j, k = wave[i][:2]
            t = _pull_back(found.centre_check(prog), failed[i])
            if t is not None and (1.0 - t) * abs(here[i][0][k] - found.centre.point[k]) \
                    <= PULLED * lp.scale[j]:
                at[i] = _between(found.centre, here[i], t, lp)
    return done, {i: c for i, c in failed.items() if done[i] is None}


def _corrected(prog: Program, lp: _LinearModel, solvers: list[_Solver],
               pool: ThreadPoolExecutor, wave: list[tuple[int, int, float]],
               ys: list[np.ndarray | None], failed: dict[int, PointCheck],
               centre: Witness | None) -> list[tuple[int, Witness | None]]:
    """The failed ends again, their LPs re-solved with the rows the checks found violated
    tightened (_end), each HiGHS model taking its share in its own thread."""
    rest, share = sorted(failed), len(solvers)

    def correct(w: int) -> list[tuple[int, Witness | None]]:
        return [(i, _end(prog, lp, solvers[w], wave[i][0], wave[i][2], centre, ys[i],
                         failed[i])[0]) for i in rest[w::share]]

    return [x for part in pool.map(correct, range(min(share, len(rest)))) for x in part]


def _pull_back(centre: PointCheck, check: PointCheck) -> float | None:
    """A share t < 1 of the way from the centre to a failed point at which the rows that
    failed there should hold (None where a row comparing two computed values failed: the
    corrections handle those). Such a row has room u at the centre to the bound it crossed,
    and crossed it by the measured excess e at the point; where the model curves at least
    as a square along the segment, the row at t is at most its centre's value plus t (u + e):
    t = u / (u + OVERSHOOT e) keeps it inside. Only the check decides."""
    assert check.ok is not None and check.computed is not None and check.side is not None
    assert centre.side is not None
    bad = ~check.ok
    if not check.in_domain or not bad.any() or np.any(bad & check.computed):
        return None
    above = check.hi[bad] > check.side[1][bad]
    room = np.where(above, centre.side[1][bad] - centre.hi[bad],
                    centre.lo[bad] - centre.side[0][bad])
    with np.errstate(all="ignore"):
        t = float(np.min(room / (room + OVERSHOOT * check.excess[bad])))
    return t if 0.0 < t < 1.0 else None


def _between(centre: Witness, at: tuple[np.ndarray, np.ndarray], t: float,
             lp: _LinearModel) -> tuple[np.ndarray, np.ndarray]:
    """The point (unknowns, readings) a share t of the way from the centre to `at` (kept in
    the box and the readings' intervals: the sum may round out of them)."""
    point = np.clip(centre.point + t * (at[0] - centre.point), *lp.box)
    return point, np.clip(centre.readings + t * (at[1] - centre.readings),
                          *lp.readings.inside)


def _refined(prog: Program, box: tuple[np.ndarray, np.ndarray], free: np.ndarray, j: int,
             sign: float, w: Witness) -> Witness | None:
    """The end again, over the model linearized at its certified point w: near the end, the
    linearization's remainder that held it back is small."""
    lp = _LinearModel(prog, box, w.point, free)
    return _end(prog, lp, lp.solver, j, sign, w)[0] if lp.finite else None


def _end(prog: Program, lp: _LinearModel, solver: _Solver, j: int, sign: float,
         toward: Witness | None, first: np.ndarray | None = None,
         failed: PointCheck | None = None) -> tuple[Witness | None, float]:
    """A certified point far along the free unknown j in the direction `sign`, from the LPs
    of `solver` (one of lp's models; `first`: the LP's optimum with no row tightened, when
    already known, and `failed` its check where it already failed), as a last resort pulled
    back towards the certified point `toward` (towards lp's own centre if None); and that
    optimum's step along j (in units of its width, nan if none): how far the linearized
    model promised."""
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
        check = failed if k == 0 and failed is not None else check_point(prog, point, readings)
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
    last = lp.point(step) if len(step) else None
    for n in range(1, PULLBACKS + 1 if last is not None else 0):
        assert last is not None
        point, readings = (_between(toward, last, 0.5**n, lp) if toward is not None
                           else lp.point(0.5**n * step))
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
