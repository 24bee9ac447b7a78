"""Point checks that evaluate only the rows a second-order bound does not already prove.

A point check (certify_point.py) evaluates every primitive of the program at each point: one
pass over every calibration row per point. Near the solution set most rows hold by a wide
margin. The rows' second-order Taylor models over a box (relax/taylor.py: each row's value
in c0 + c1.t + c2.m(t) + [-r, r] for every t in [-1, 1]^n and every reading within its
interval) bound a row at a point of the box with a few float products, their roundings
bounded here; a row whose bound lies inside its measured interval's exact inside holds
there, whatever the readings within their intervals; one whose bound lies outside the
target's enclosure fails there, whatever the readings (no evaluation could prove the
point). The loop's rows (configurations) with a row the bound leaves open are checked by
interval evaluation, each a chunk of the program (compile/chunks.py), at just the points
that need it. A point holds when it lies in
the domains and every row is proven by one or the other (where the evaluation fails only
rows comparing two computed values, existence.py's proof is tried, as for a whole check).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from calib_dsl.analysis.certify_point import (
    PointCheck,
    box_rows,
    check_points,
    exact_inside,
    reading_slots,
)
from calib_dsl.analysis.existence import prove_point
from calib_dsl.compile.chunks import chunked
from calib_dsl.ir.program import Program, derived
from calib_dsl.relax.layout import independents
from calib_dsl.relax.models import Models, U, up
from calib_dsl.relax.taylor import Expansion, expand
from calib_dsl.settings import Settings

_BLOCK = 256  # points a block of the bounds' products: (points, rows) matrices stay small
# (module attribute, the settings' declared value: tests make blocks small)
SIZE_ROWS = Settings.blocks.size_rows


@dataclass(frozen=True)
class RowScreen:
    """The models of `prog`'s rows over the box [lo, hi] (its independents), each row's
    target's exact inside and its loop row (-1: the shared part); `always` (per loop row, the
    last entry the shared part's): whether it has a checked row no model covers."""

    prog: Program
    ex: Expansion
    lo: np.ndarray
    hi: np.ndarray
    inside: tuple[np.ndarray, np.ndarray]
    config: np.ndarray
    always: np.ndarray
    # the models' coefficients of (t, the products t_i t_j), one column a row (made once:
    # every block of points multiplies by them; ex's models' c1 and c2 are views of it), and
    # per row an upper bound on the sum of their magnitudes (every term lies in [-1, 1])
    coef: np.ndarray
    size: np.ndarray
    # above this share of the points' loop rows left open, a pass is the whole check
    most_open: float = 1.0
    # every checked row enclosed over the box, each reading over its interval (box_rows),
    # and its loop row (-1: the shared part): what screened_checks fills a proven row with
    whole: PointCheck | None = None
    whole_config: np.ndarray | None = None


def row_screen(prog: Program, lo: np.ndarray, hi: np.ndarray, most_open: float = 1.0
               ) -> RowScreen | None:
    """The screen of `prog`'s rows over the box [lo, hi] of its independents (within their
    domains); None where the program has no loop compiled once or no second-order models.
    `most_open`: the share of the points' loop rows left open above which a pass evaluates
    the whole program at every point decided by no model (in chunks of many points and
    rows: cheaper a row than one-row chunks at a few points each). Made once per program
    and box (the inner bounds and the predictions' extremes search the same box)."""
    # (outside derived's lock: the build runs threads, which may build other tables)
    made = derived(prog, _key(lo, hi), lambda: _row_screen(prog, lo, hi), wait=False)
    return None if made is None else replace(made, most_open=most_open)


def forget(prog: Program, lo: np.ndarray, hi: np.ndarray) -> None:
    """Drop the screen kept for the box [lo, hi] (its models hold some 200 bytes per unknown
    and row: a large program's should not outlive the search that made it)."""
    prog.derived_cache.pop(_key(lo, hi), None)


def _key(lo: np.ndarray, hi: np.ndarray) -> str:
    return f"row screen {lo.tobytes().hex()}{hi.tobytes().hex()}"


def _row_screen(prog: Program, lo: np.ndarray, hi: np.ndarray) -> RowScreen | None:
    lay = prog.rows
    ind = independents(prog)
    if lay is None or not len(ind):
        return None
    slo, shi = prog.slots.lo.copy(), prog.slots.hi.copy()
    slo[ind], shi[ind] = lo, hi  # (the readings and measurements: their own intervals)
    ex = expand(prog, slo, shi, by_terms=True)
    if ex is None:
        return None
    configs = len(lay.rows)

    def config_of(slots: np.ndarray) -> np.ndarray:
        return np.where(slots >= lay.shared, (slots - lay.shared) // max(lay.width, 1), -1)

    # every checked row (a point check's rows do not depend on the point, nor the box's
    # pass's): those no model bounds (capped temporaries, two computed sides) are always
    # evaluated
    whole = box_rows(prog, lo, hi)
    assert whole.computed is not None
    modelled = np.isin(whole.slots, ex.rows.slots) & ~whole.computed
    always = np.zeros(configs + 1, dtype=bool)
    always[config_of(whole.slots[~modelled])] = True
    coef = ex.coef
    if coef is None:  # (a program expanded whole: its models copied once, and dropped)
        m = ex.rows.models
        n = m.c1.shape[1]
        coef = np.empty((n + m.c2.shape[1], len(m.c0)))
        coef[:n], coef[n:] = m.c1.T, m.c2.T
        models = Models(m.c0, coef[:n].T, coef[n:].T, m.r)
        ex = replace(ex, rows=replace(ex.rows, models=models), coef=coef)
        del m
    return RowScreen(prog, ex, lo.copy(), hi.copy(), exact_inside(ex.rows.lo, ex.rows.hi),
                     config_of(ex.rows.slots), always, coef, row_sizes(coef, SIZE_ROWS), 1.0,
                     whole, config_of(whole.slots))


def row_sizes(coef: np.ndarray, block: int) -> np.ndarray:
    """Per column of `coef` (a row's coefficients), an upper bound on the sum of its
    entries' magnitudes, `block` columns at a time (the magnitudes of a block only are
    made: a copy of the whole would double the screen's memory)."""
    out, block = np.zeros(coef.shape[1]), max(1, block)
    for a in range(0, coef.shape[1], block):
        part = np.abs(coef[:, a:a + block])
        for k in range(len(part)):  # (term by term: the same sums for any block)
            out[a:a + block] += part[k]
    return up(out)


def screened_checks(screen: RowScreen, points: np.ndarray, readings: np.ndarray
                    ) -> list[PointCheck]:
    """check_points(prog, points, readings) where every point lies in the screen's box,
    evaluating only the loop rows (configurations) some point's models leave open (their
    union: one pass of chunks of many rows, every point in each) and the shared part's. A
    row the models prove at every point is filled in as held (`ok`, no excess), its
    computed side the box's enclosure (which holds the point's): its verdict is proven, and
    the callers read the values of the rows that failed only (inner/bounds._pull_back,
    LinearModel.excess), which were evaluated at the point as by a check of every row."""
    prog, lay, w = screen.prog, screen.prog.rows, screen.whole
    inside = np.all((points >= screen.lo) & (points <= screen.hi))
    if lay is None or w is None or screen.whole_config is None or not inside:
        return check_points(prog, points, readings)
    # (the union, a block of points at a time: once it holds every loop row, the pass is
    # the whole check, and the other points' models are not worth their products)
    union = np.zeros(len(lay.rows), dtype=bool)
    for a in range(0, len(points), _BLOCK):
        union |= _needs(screen, points[a:a + _BLOCK])[0][:, :-1].any(axis=0)
        if union.all():
            return check_points(prog, points, readings)
    rows = np.flatnonzero(union)
    if not len(rows):
        rows = np.zeros(1, dtype=np.int64)  # (a check takes some loop row with the shared)
    part = check_points(prog, points, readings, rows=rows)
    mask = (screen.whole_config < 0) | np.isin(screen.whole_config, rows)
    if not np.array_equal(part[0].slots, w.slots[mask]):
        raise AssertionError("a check of some rows gave other rows than the box's pass")
    return [_filled(w, mask, c) for c in part]


def _filled(w: PointCheck, m: np.ndarray, c: PointCheck) -> PointCheck:
    """The check of every row: `c`'s rows (those of the mask `m`), the others held (their
    values from the box's pass `w`)."""
    assert c.ok is not None and c.computed is not None and c.side is not None
    assert w.side is not None and w.computed is not None

    def put(base: np.ndarray, part: np.ndarray) -> np.ndarray:
        out = base.copy()
        out[m] = part
        return out

    n = len(w.slots)
    ok = put(np.ones(n, dtype=bool), c.ok)
    return PointCheck(bool(np.all(ok)) and c.in_domain, w.slots, put(w.lo, c.lo),
                      put(w.hi, c.hi), put(np.zeros(n), c.excess), ok,
                      put(w.computed, c.computed),
                      (put(w.side[0], c.side[0]), put(w.side[1], c.side[1])), None,
                      c.in_domain)


def screened_holds(screen: RowScreen, points: np.ndarray, readings: np.ndarray
                   ) -> np.ndarray:
    """Per point (independents' order, with its readings in reading_slots' order): whether it
    satisfies every constraint of the screen's program for some values of its measured
    intervals (check_points' `holds`, or prove_point's where that is needed)."""
    prog = screen.prog
    need, false = _needs(screen, points)  # (points, loop rows + 1): evaluate that chunk
    ind = independents(prog)
    dlo, dhi = exact_inside(prog.slots.lo[ind], prog.slots.hi[ind])
    holds = np.all(points >= dlo, axis=1) & np.all(points <= dhi, axis=1) & ~false
    if need[holds, :-1].sum() > screen.most_open * holds.sum() * (need.shape[1] - 1):
        return _whole(prog, points, readings, holds)
    # a shared row left unproven is evaluated with some loop row's chunk (each has the
    # shared part): the first that point needs anyway, else row 0
    alone = need[:, -1] & ~need[:, :-1].any(axis=1)
    need[alone, 0] = True
    only_computed = np.ones(len(points), dtype=bool)
    lay = prog.rows
    assert lay is not None
    at = reading_slots(prog)
    for j in np.flatnonzero(need[:, :-1].any(axis=0)):
        some = np.flatnonzero(need[:, j] & holds)
        if not len(some):
            continue
        ch = chunked(prog, lay.shared + lay.width, np.array([j]))
        assert ch is not None and len(ch) == 1
        c = ch[0]
        mine = readings[some][:, np.searchsorted(at, c.slots(reading_slots(c.prog)))]
        checks = check_points(c.prog, points[some], mine,
                              box=(c.box(prog.slots.lo), c.box(prog.slots.hi)))
        keep = c.kept(checks[0].slots)
        for i, chk in zip(some, checks, strict=True):
            assert chk.ok is not None and chk.computed is not None
            bad = keep & ~chk.ok
            if bad.any():
                holds[i] = False
                only_computed[i] &= not np.any(bad & ~chk.computed)
    # rows comparing two computed values: the whole check's existence proof, as check_points'
    # callers try it
    for i in np.flatnonzero(~holds & only_computed & ~false & np.all(points >= dlo, axis=1)
                            & np.all(points <= dhi, axis=1)):
        holds[i] = prove_point(prog, points[i], readings[i])
    return holds


def holds(prog: Program, points: np.ndarray, readings: np.ndarray) -> np.ndarray:
    """Each point proven consistent (check_points, prove_point where it fails) or not."""
    return _whole(prog, points, readings, np.ones(len(points), dtype=bool))


def _whole(prog: Program, points: np.ndarray, readings: np.ndarray, some: np.ndarray
           ) -> np.ndarray:
    """check_points' verdicts (prove_point's where needed) for the points `some`, False for
    the others."""
    holds = np.zeros(len(points), dtype=bool)
    at = np.flatnonzero(some)
    if len(at):
        checks = check_points(prog, points[at], readings[at])
        holds[at] = [c.holds or prove_point(prog, points[i], readings[i], c)
                     for i, c in zip(at, checks, strict=True)]
    return holds


def _needs(screen: RowScreen, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(points, loop rows + 1): which loop rows (the last column: the shared part) have a row
    the models do not prove inside its target at the point, every one for a point outside
    the models' box; and per point, whether the models prove some row false there."""
    configs = len(screen.always) - 1
    need = np.tile(screen.always, (len(points), 1))
    false = np.zeros(len(points), dtype=bool)
    inside = np.all((points >= screen.lo) & (points <= screen.hi), axis=1)
    need[~inside] = True
    at = np.flatnonzero(inside)
    col = np.where(screen.config >= 0, screen.config, configs)
    for a in range(0, len(at), _BLOCK):
        block = at[a:a + _BLOCK]
        holds, fails = _judged(screen, points[block])
        hit = np.zeros((len(block), configs + 1), dtype=bool)
        rows, cols = np.nonzero(~holds)
        hit[rows, col[cols]] = True
        need[block] |= hit
        false[block] = fails.any(axis=1)
    return need, false


def _proven(screen: RowScreen, points: np.ndarray) -> np.ndarray:
    """(points, rows): whether the row's model bounds its value at the point inside its
    target's exact inside (_judged's first)."""
    return _judged(screen, points)[0]


def _judged(screen: RowScreen, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(points, rows) twice, at points inside the models' box: whether the row's model bounds
    its value inside its target's exact inside (the row holds), and outside the target's
    float enclosure (it fails, for every reading within its interval), every rounding of the
    float evaluation bounded: the terms' magnitudes times (terms + 16) 4U (each product, sum
    and the point's own t = (p - c) / w contribute a few U of a term's magnitude), the terms'
    magnitudes bounded by the coefficients' (every t_i and product lies in [-1, 1])."""
    ex = screen.ex
    m = ex.rows.models
    # exact t lies in [-1, 1] (the half-widths are rounded up): clipping only moves the
    # float t towards it
    t = np.clip((points - ex.center) / ex.half, -1.0, 1.0)
    terms = np.hstack([t, t[:, ex.pairs.i] * t[:, ex.pairs.j]])
    value = m.c0[None, :] + terms @ screen.coef
    size = (np.abs(m.c0) + screen.size)[None, :]
    count = terms.shape[1] + 16
    err = size * (count * 4 * U) + 1e-300
    reach = m.r[None, :] + err
    # (the two sums below round too: a few U of their magnitudes, far inside 2^-40)
    slack = reach + 2.0**-40 * (np.abs(value) + reach)
    tlo, thi = screen.inside
    with np.errstate(invalid="ignore"):
        holds = (value - slack >= tlo[None, :]) & (value + slack <= thi[None, :])
        fails = (value + slack < ex.rows.lo[None, :]) | (value - slack > ex.rows.hi[None, :])
    return holds, fails
