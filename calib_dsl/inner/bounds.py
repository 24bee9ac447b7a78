"""Certified inner bounds: for each unknown, an interval [a, b] inside the hull of the solution
set, so that outer/inner widths say how much of an enclosure is real.

a and b are coordinates of parameter vectors that certify_point.py proves to satisfy every
constraint (interval evaluation at the point, outward rounding: floating point is never
trusted). The candidates are the extremes of each unknown over the model linearized at the
box's middle (one LP per end, the same LP re-solved with another objective, from the solve's
final basis for that end where it kept one: inner/starts.py). A wave of them is checked in one
pass; one that fails is pulled back towards a certified centre by what the check measured,
else the rows it violates are tightened and its LP is solved again, and as a last resort it
is pulled back by halves. An end that this left well short of its LP's optimum is sought
again over the model linearized at its point, and again from there while that gains
(sequential linearization). Every certified point adds to every unknown's interval.
"""

from __future__ import annotations

import time
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from calib_dsl.analysis.certify_point import PointCheck, check_points, exact_inside
from calib_dsl.analysis.chebyshev import chebyshev
from calib_dsl.analysis.existence import prove_point
from calib_dsl.analysis.readings import Readings
from calib_dsl.analysis.row_screen import forget
from calib_dsl.inner.lp import LinearModel, Solver
from calib_dsl.inner.screen import checks
from calib_dsl.inner.starts import Starts
from calib_dsl.ir.program import Program
from calib_dsl.relax.chunked import release_freed
from calib_dsl.relax.layout import independents
from calib_dsl.settings import InnerSettings, LPSettings, Settings


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
    witnesses: tuple[Witness, ...]  # in the order found
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

    @cached_property
    def centre(self) -> Witness | None:
        """The certified point nearest the middle of the inner intervals (each unknown
        measured in its interval's width): a parameter vector proven consistent, for an
        export that wants one (None: none certified)."""
        if not self.witnesses:
            return None
        with np.errstate(invalid="ignore"):
            mid, width = 0.5 * (self.lo + self.hi), self.hi - self.lo
            scale = np.where(np.isfinite(width) & (width > 0), width, 1.0)
            off = [np.nansum(((w.point - mid) / scale) ** 2) for w in self.witnesses]
        return self.witnesses[int(np.argmin(off))]


def inner_bounds(prog: Program, lo: np.ndarray, hi: np.ndarray,
                 starts: Starts | None = None, settings: Settings | None = None) -> Inner:
    """Certified inner intervals of the unknowns, searched within the outer box [lo, hi] (over
    the program's slots: the solve's result); each end's LP from the solve's final basis for
    that end where `starts` has one (the same rows and columns near the same optimum: far
    fewer pivots than from scratch)."""
    settings = settings or Settings()
    start = time.perf_counter()
    ind = independents(prog)
    names = tuple(prog.slots.names[i] for i in ind)
    # within the result, and within the declared domains exactly (their floats are rounded
    # outward; a domain a few ulps wide keeps its float bounds and certifies nothing)
    dlo, dhi = exact_inside(prog.slots.lo[ind], prog.slots.hi[ind])
    some = dlo <= dhi
    box = (np.where(some, np.maximum(lo[ind], dlo), lo[ind]).astype(float),
           np.where(some, np.minimum(hi[ind], dhi), hi[ind]).astype(float))
    found = _Points(len(ind), box)
    # (the solve's freed memory back to the system before this phase's threads allocate
    # the row screen and the LPs, and the screen's once it is dropped)
    release_freed()
    try:
        _search(prog, box, found, starts, (settings.lp, settings.inner))
    finally:
        forget(prog, *box)  # (the checks' screen: inner/screen.py)
        release_freed()
    return Inner(names, found.lo, found.hi, tuple(found.all), found.lo_at, found.hi_at,
                 time.perf_counter() - start)


class _Points:
    """The certified points seen so far, and per unknown the range they span; `centre`, the
    point that failed candidates are pulled back towards (None until one is certified)."""

    def __init__(self, n: int, box: tuple[np.ndarray, np.ndarray]) -> None:
        self.box = box  # (every candidate lies in it: inner/screen.py screens its rows)
        self.lo, self.hi = np.full(n, np.nan), np.full(n, np.nan)
        self.lo_at, self.hi_at = np.full(n, -1), np.full(n, -1)
        self.all: list[Witness] = []
        self.centre: Witness | None = None
        self._centre_check: PointCheck | None = None
        self.fitted = False  # whether the Chebyshev fit was tried as the centre

    def add(self, w: Witness) -> None:
        k = len(self.all)
        self.all.append(w)
        lower, higher = ~(w.point >= self.lo), ~(w.point <= self.hi)  # nan: none yet
        self.lo[lower], self.lo_at[lower] = w.point[lower], k
        self.hi[higher], self.hi_at[higher] = w.point[higher], k

    def add_centre(self, w: Witness) -> None:
        self.centre, self._centre_check = w, None
        self.add(w)

    def centre_check(self, prog: Program) -> PointCheck:
        """The centre's check of every row (not screened: a row its models prove there may
        fail at another point, and its room at the centre is then read): each row's room
        to its bounds there."""
        assert self.centre is not None
        if self._centre_check is None:
            self._centre_check = check_points(prog, self.centre.point[None],
                                              self.centre.readings[None])[0]
        return self._centre_check


def _search(prog: Program, box: tuple[np.ndarray, np.ndarray], found: _Points,
            starts: Starts | None, settings: tuple[LPSettings, InnerSettings]) -> None:
    """The certified points: the box's middle if it is one; then both ends of every unknown
    that can move, over the model linearized at the middle, or at the Chebyshev fit where it
    cannot be linearized there or its LPs gave no point (a wide box: the middle's linear
    model may have no solution)."""
    lo, hi = box
    mid = np.where(np.isfinite(lo) & np.isfinite(hi), 0.5 * (lo + hi), np.clip(0.0, lo, hi))
    mid = np.clip(mid, lo, hi)
    middles = Readings(prog).middles()
    if prove_point(prog, mid, middles):  # a tight box's middle often is a solution
        found.add_centre(Witness(mid, middles))
    free = np.flatnonzero(hi > lo)
    if not len(free):
        return
    lp = LinearModel(prog, box, mid, free, starts, *settings)
    if lp.finite:
        _extremes(prog, box, lp, found)
    if found.all:
        return
    if not found.fitted and (centre := _fit(prog, box, mid, settings[1].settle)) is not None:
        found.add_centre(centre)
    found.fitted = True
    if found.centre is not None and not np.array_equal(found.centre.point, mid):
        lp = LinearModel(prog, box, found.centre.point, free, starts, *settings)
        if lp.finite:
            _extremes(prog, box, lp, found)


def _fit(prog: Program, box: tuple[np.ndarray, np.ndarray], mid: np.ndarray,
         settle: float) -> Witness | None:
    """The point with the smallest largest residual (in units of each row's bound, the
    readings at their middles), from the middle, if it is certified: a centre where the
    mean of the first wave's ends is not one."""
    middles = Readings(prog).middles()
    try:
        with np.errstate(all="ignore"):
            p, need = chebyshev(prog, normalized=True, start=mid, box=box, target=1.0,
                                settle=settle)
    except (ValueError, np.linalg.LinAlgError):
        return None
    if need < 1.0 and np.all(np.isfinite(p)) and prove_point(prog, p, middles):
        return Witness(p, middles)
    return None


def _extremes(prog: Program, box: tuple[np.ndarray, np.ndarray], lp: LinearModel,
              found: _Points) -> None:
    """Both ends of every unknown that can move, over the linearized model `lp`; then
    those that fell well short, over the model linearized at their own points (a tall
    model's LPs there start from the rows the first LPs came to hold: the rows that bound
    the ends do not change much from one linearization to the next; docs/decisions/31)."""
    solvers = lp.solvers(lp.lp_settings.workers)
    with ThreadPoolExecutor(len(solvers)) as pool:
        short = _waves(prog, lp, solvers, pool, found)
        held = np.unique(np.concatenate([s.in_lp for s in solvers]))
        for points in pool.map(lambda end: _refined(prog, box, lp, end, held), short):
            for w in points:
                found.add(w)


def _waves(prog: Program, lp: LinearModel, solvers: list[Solver], pool: ThreadPoolExecutor,
           found: _Points) -> list[tuple[int, float, Witness]]:
    """The ends not yet reached, in waves of `wave` (InnerSettings). The HiGHS models solve
    a wave's LPs in their threads (HiGHS releases the GIL) while this thread checks the wave
    before, so a wave is chosen before the points of the one just solved count: in the same
    order on every run. Returns the ends (j, sign, point) whose point fell short of their LP's
    optimum by `refine`."""
    lo, hi = lp.box
    ends = [(j, int(k), sign) for j, k in enumerate(lp.free) for sign in (-1.0, 1.0)]
    share, untightened = len(solvers), np.zeros(lp.rows)

    def unreached(k: int, sign: float) -> bool:
        reached, bound = (found.hi[k], hi[k]) if sign > 0 else (found.lo[k], lo[k])
        return not abs(bound - reached) <= lp.inner.reached * (hi[k] - lo[k])

    def optima(wave: list[tuple[int, int, float]], w: int) -> list[np.ndarray | None]:
        return [solvers[w].extreme(j, sign, untightened, lp.start(j, sign))
                for j, _, sign in wave[w::share]]

    def launch() -> tuple[list[tuple[int, int, float]], list[Future]]:
        wave: list[tuple[int, int, float]] = []
        while ends and len(wave) < lp.inner.wave:
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
                if sign * (y[j] - (w.point[k] - lp.centre[k]) / lp.scale[j]) > lp.inner.refine:
                    short.append((j, sign, w))
        wave, ys = after, ys_after
    return short


def _checked(prog: Program, lp: LinearModel, wave: list[tuple[int, int, float]],
             ys: list[np.ndarray | None], found: _Points
             ) -> tuple[list[Witness | None], dict[int, PointCheck]]:
    """The wave's LP optima checked in one pass (with their mean, a centre, while there is
    none); those that fail on plain rows pulled back towards the centre by what the check
    measured (_pull_back) and checked in one more. Returns the certified points (None where
    none yet) and the checks of the optima still failing."""
    done: list[Witness | None] = [None] * len(wave)
    at = {i: lp.point(y) for i, y in enumerate(ys) if y is not None}
    if found.centre is None and at:
        at[-1] = lp.point(np.mean([y for y in ys if y is not None], axis=0))
    failed = _certified(prog, at, done, found)
    if failed and found.centre is None and not found.fitted:
        found.fitted = True  # (once: a later wave's mean may still be a centre)
        if (centre := _fit(prog, lp.box, lp.centre, lp.inner.settle)) is not None:
            found.add_centre(centre)
    if found.centre is not None:
        pulled = {}
        for i in sorted(failed):
            j, k = wave[i][:2]
            t = _pull_back(found.centre_check(prog), failed[i], lp.inner.overshoot)
            if t is not None and (1.0 - t) * abs(at[i][0][k] - found.centre.point[k]) \
                    <= lp.inner.pulled * lp.scale[j]:
                pulled[i] = _between(found.centre, at[i], t, lp)
        _certified(prog, pulled, done, found)
    return done, {i: c for i, c in failed.items() if done[i] is None}


def _certified(prog: Program, at: dict[int, tuple[np.ndarray, np.ndarray]],
               done: list[Witness | None], found: _Points) -> dict[int, PointCheck]:
    """The points `at` (unknowns, readings) checked in one pass: each one proven goes into
    `done` at its index (-1: the centre, into `found`); returns the checks of the others."""
    order = sorted(at)
    if not order:
        return {}
    done_checks = checks(prog, found.box, np.array([at[i][0] for i in order]),
                         np.array([at[i][1] for i in order]))
    failed = {}
    for i, check in zip(order, done_checks, strict=True):
        point, readings = at[i]
        if not (check.holds or prove_point(prog, point, readings, check)):
            failed[i] = check
        elif i < 0:
            found.add_centre(Witness(point, readings))
        else:
            done[i] = Witness(point, readings)
    failed.pop(-1, None)
    return failed


def _corrected(prog: Program, lp: LinearModel, solvers: list[Solver],
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


def _pull_back(centre: PointCheck, check: PointCheck, overshoot: float) -> float | None:
    """A share t < 1 of the way from the centre to a failed point at which the rows that
    failed there should hold (None where a row comparing two computed values failed: the
    corrections handle those). Such a row has room u at the centre to the bound it crossed,
    and crossed it by the measured excess e at the point; where the model curves at least
    as a square along the segment, the row at t is at most its centre's value plus t (u + e):
    t = u / (u + overshoot e) keeps it inside. Only the check decides."""
    assert check.ok is not None and check.computed is not None and check.side is not None
    assert centre.side is not None
    bad = ~check.ok
    if not check.in_domain or not bad.any() or np.any(bad & check.computed):
        return None
    above = check.hi[bad] > check.side[1][bad]
    room = np.where(above, centre.side[1][bad] - centre.hi[bad],
                    centre.lo[bad] - centre.side[0][bad])
    with np.errstate(all="ignore"):
        t = float(np.min(room / (room + overshoot * check.excess[bad])))
    return t if 0.0 < t < 1.0 else None


def _between(centre: Witness, at: tuple[np.ndarray, np.ndarray], t: float,
             lp: LinearModel) -> tuple[np.ndarray, np.ndarray]:
    """The point (unknowns, readings) a share t of the way from the centre to `at` (kept in
    the box and the readings' intervals: the sum may round out of them)."""
    point = np.clip(centre.point + t * (at[0] - centre.point), *lp.box)
    return point, np.clip(centre.readings + t * (at[1] - centre.readings),
                          *lp.readings.inside)


def _refined(prog: Program, box: tuple[np.ndarray, np.ndarray], first: LinearModel,
             end: tuple[int, float, Witness], held: np.ndarray) -> list[Witness]:
    """The end (j, sign, its certified point) again, over the model linearized at its
    certified point, where the linearization's remainder that held it back is small; and
    again from the point that gives while it still falls short of its LP's optimum by
    `refine` and gained that much on the last (sequential linearization, `refine_steps` at
    most: the end of a thin solution set curves away from any one linearization). Returns
    the certified points found on the way."""
    j, sign, w = end
    k, inner, got = int(first.free[j]), first.inner, []
    for _ in range(inner.refine_steps):
        lp = LinearModel(prog, box, w.point, first.free, first.starts, first.lp_settings,
                         inner)
        if not lp.finite:
            break
        same = lp.rows == first.rows and np.array_equal(lp.slots, first.slots)
        point, promised = _end(prog, lp, lp.solvers(1, held if same else None)[0], j, sign, w)
        if point is None:
            break
        got.append(point)
        gained = sign * (point.point[k] - w.point[k]) / lp.scale[j]
        short = sign * (promised - (point.point[k] - lp.centre[k]) / lp.scale[j])
        if not (gained > inner.refine and short > inner.refine):
            break
        w = point
    return got


def _end(prog: Program, lp: LinearModel, solver: Solver, j: int, sign: float,
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
    inner = lp.inner
    promised = np.nan
    for k in range(inner.corrections):
        y = first if k == 0 and first is not None else \
            solver.extreme(j, sign, tighten, lp.start(j, sign) if k == 0 else None)
        if y is None:  # tightened beyond what the LP can meet
            break
        step = y
        promised = float(y[j]) if k == 0 else promised
        point, readings = lp.point(step)
        if k == 0 and failed is not None:
            check = failed  # (checked, and not proven, with its wave)
        else:
            check = checks(prog, lp.box, point[None], readings[None])[0]
            if check.holds or prove_point(prog, point, readings, check):
                return Witness(point, readings), promised
        excess, computed = lp.excess(check)
        # a row that fails again was not binding in the LP: its remainder exceeds what it
        # was tightened by, so aim further inside, fourfold
        again = (excess > 0) & (tighten > 0)
        tighten += inner.overshoot * excess
        tighten[again] = np.maximum(tighten[again], inner.escalate
                                    * (tighten[again] - inner.overshoot * excess[again]))
        # a row between two computed values fails by its remainder, not by its (whole)
        # difference: aim further inside, doubling
        tighten[computed] = np.maximum(2.0 * tighten[computed], inner.computed_aim)
    last = lp.point(step) if len(step) else None
    for n in range(1, inner.pullbacks + 1 if last is not None else 0):
        assert last is not None
        point, readings = (_between(toward, last, 0.5**n, lp) if toward is not None
                           else lp.point(0.5**n * step))
        if prove_point(prog, point, readings):
            return Witness(point, readings), promised
    return None, promised
