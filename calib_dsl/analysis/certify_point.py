"""A proof that a parameter vector satisfies every constraint: interval evaluation at a point.

Consistency asks for values within the bounds that satisfy every constraint. The witness:
every declared unknown at the point, and every measured value that only enters the model
(a joint reading: an argument, never a compared side) at a value within its interval (the
middle unless the caller gives one). Each primitive is then evaluated forward with outward
rounding; a temporary takes the value its definition gives, and every other row (`f == x`
with x measured, or a second definition of a temporary) must hold: f's enclosure inside x's
interval, shrunk by the rounding that made it (so inside the exact one). Then some
measurement errors within their bounds make the point satisfy every constraint: the data are
consistent. Floating point is never trusted. Where a row compares two computed values, the
test cannot prove it (an interval equals an interval only when both are points) and says so.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import reduce

import numpy as np

from calib_dsl.arith.projections import forward
from calib_dsl.compile.chunks import Chunk, chunked
from calib_dsl.ir.program import Program, derived
from calib_dsl.relax.chunked import in_threads
from calib_dsl.relax.gradients import OUTPUTS
from calib_dsl.relax.layout import definitions, independents
from calib_dsl.relax.ownership import NONE, combine


@dataclass(frozen=True)
class PointCheck:
    holds: bool
    # per checked row: its slot (the measured or bounded side), the enclosure of the computed
    # side, and how far it sticks out of the slot's interval (0: inside)
    slots: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    excess: np.ndarray
    # per row: whether it holds; whether it compares two computed values (then `lo, hi`
    # minus `side` is the difference of the two); its other side's enclosure (the exact
    # interval's inside for a measured value); the configuration (table row id) of the
    # readings it depends on (NONE, or MIXED for more than one: relax/ownership.py)
    ok: np.ndarray | None = None
    computed: np.ndarray | None = None
    side: tuple[np.ndarray, np.ndarray] | None = None
    owner: np.ndarray | None = None
    in_domain: bool = True


def reading_slots(prog: Program) -> np.ndarray:
    """The measured values that only enter the model (joint readings: arguments, never a
    compared side): the witness may give each a value within its interval (made once per
    program)."""
    return derived(prog, "reading slots", lambda: _reading_slots(prog))


def _reading_slots(prog: Program) -> np.ndarray:
    n = len(prog.slots.lo)
    compared, argument = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    for g in prog.groups:
        compared[g.out[g.out >= 0]] = True
        argument[g.args[g.args >= 0]] = True
    cells = prog.slots.cell_row
    if cells is None:
        return np.zeros(0, dtype=np.int64)
    lo, hi = prog.slots.lo, prog.slots.hi
    return np.flatnonzero((cells >= 0) & argument & ~compared & np.isfinite(lo)
                          & np.isfinite(hi))


def check_point(prog: Program, point: np.ndarray, readings: np.ndarray | None = None,
                owners: bool = False) -> PointCheck:
    """Whether `point` (the declared unknowns, in `independents` order) satisfies every
    constraint of `prog` for some value of its measured intervals: the readings' values
    (`reading_slots` order; their midpoints if None) and any value of the compared sides.
    With `owners`, each row's configuration too (existence.py needs it)."""
    return check_points(prog, point[None], None if readings is None else readings[None],
                        owners)[0]


# Slots times points evaluated in one pass at most (each array of the pass 8 bytes a cell): a
# program of many slots checks fewer points at once (32 MB an array)
CHECK_CELLS = 4_000_000
# Slots times points of a pass over a chunk of a loop's rows: a pass's arrays (8 MB each)
# stay near the cache, where a pass over the whole program reads its slots from memory once
# per primitive that reads them; and each primitive group's Python work (under the
# interpreter's lock, which a check on another thread waits for) is spread over that many
# cells (docs/decisions/69)
CHUNK_CELLS = 1_000_000


def check_points(prog: Program, points: np.ndarray, readings: np.ndarray | None = None,
                 owners: bool = False, box: tuple[np.ndarray, np.ndarray] | None = None,
                 rows: np.ndarray | None = None) -> list[PointCheck]:
    """check_point for each row of `points` (with the same row of `readings`): one pass over
    the program's primitives for as many as CHECK_CELLS allows (a check's cost is mostly the
    pass over the primitives, not the points in it). A program of a loop compiled once
    larger than CHUNK_CELLS is checked a chunk of its rows at a time, every point in one
    pass over a chunk. `box`: the slots' domains and measured intervals (the program's own
    if None: a chunk's program is given its rows'). `rows`: the loop rows to check (not
    empty; increasing), each check then of theirs and the shared part's rows only, in the
    order a check of every row gives them (its `holds` says nothing of the others)."""
    if not len(points):
        return []
    k = len(points)
    if rows is not None:
        chunks = chunked(prog, max(1, CHUNK_CELLS // k), rows)
        assert chunks is not None
        return _verdicts(prog, _chunked(prog, chunks, points, readings, owners, box))
    if len(prog.slots.lo) * k > CHUNK_CELLS:
        chunks = chunked(prog, max(1, CHUNK_CELLS // k))
        if chunks is not None:
            return _verdicts(prog, _chunked(prog, chunks, points, readings, owners, box))
    at_once = max(1, CHECK_CELLS // max(1, len(prog.slots.lo)))
    if k > at_once:
        return [c for j in range(0, k, at_once)
                for c in check_points(prog, points[j:j + at_once],
                                      None if readings is None else readings[j:j + at_once],
                                      owners, box)]
    return _verdicts(prog, _evaluate(prog, points, readings, owners, box))


@dataclass(frozen=True)
class _Rows:
    """The checked rows of a pass, each point a column: their slots, the computed side
    [a, b], the other side [tlo, thi], whether it is computed too, their configurations
    (None unless asked); `parts`: how many rows each group output gave (then the capped
    temporaries), in order."""

    s: np.ndarray
    a: np.ndarray
    b: np.ndarray
    tlo: np.ndarray
    thi: np.ndarray
    computed: np.ndarray
    owners: np.ndarray | None
    in_domain: np.ndarray
    parts: list[int]


def _chunked(prog: Program, chunks: list[Chunk], points: np.ndarray | None,
             readings: np.ndarray | None, owners: bool,
             box: tuple[np.ndarray, np.ndarray] | None) -> _Rows:
    """The rows of the whole program, evaluated a chunk of its rows at a time and put in
    the order one pass over the whole program gives them (each group output's rows: the
    shared part's, then row after row)."""
    base = box if box is not None else (prog.slots.lo, prog.slots.hi)
    at = reading_slots(prog)

    def one(ch: Chunk) -> tuple[_Rows, np.ndarray]:
        mine = None if readings is None else \
            readings[:, np.searchsorted(at, ch.slots(reading_slots(ch.prog)))]
        r = _evaluate(ch.prog, points, mine, owners, (ch.box(base[0]), ch.box(base[1])))
        keep = ch.kept(r.s)
        return (_Rows(ch.slots(r.s[keep]), r.a[keep], r.b[keep], r.tlo[keep], r.thi[keep],
                      r.computed[keep], None if r.owners is None else ch.row_ids(r.owners[keep]),
                      r.in_domain, []),
                np.repeat(np.arange(len(r.parts)), r.parts)[keep])  # each kept row's output

    # (the chunks shared among threads, joined in their order: relax/chunked.py)
    done = in_threads(one, chunks)
    got, parts = [g for g, _ in done], [p for _, p in done]
    # (a stable sort by group output keeps each one's rows in the chunks' order: the rows')
    order = np.argsort(np.concatenate(parts), kind="stable")

    def joined(field: str) -> np.ndarray:
        return np.concatenate([getattr(g, field) for g in got])[order]

    return _Rows(joined("s"), joined("a"), joined("b"), joined("tlo"), joined("thi"),
                 joined("computed"), joined("owners") if owners else None, got[0].in_domain,
                 [])


def box_rows(prog: Program, lo: np.ndarray, hi: np.ndarray) -> PointCheck:
    """Every checked row of check_points, in its order, its computed side enclosed over the
    box [lo, hi] of the independents (within their domains) and every reading over its
    interval: a row `ok` here holds at every point of the box, whatever the readings."""
    slo, shi = prog.slots.lo.copy(), prog.slots.hi.copy()
    ind = independents(prog)
    slo[ind], shi[ind] = lo, hi  # (a reading's float interval holds its exact one)
    chunks = chunked(prog, CHUNK_CELLS) if len(slo) > CHUNK_CELLS else None
    r = _chunked(prog, chunks, None, None, False, (slo, shi)) if chunks else \
        _evaluate(prog, None, None, False, (slo, shi))
    return _verdicts(prog, r)[0]


def _evaluate(prog: Program, points: np.ndarray | None, readings: np.ndarray | None,
              owners: bool, box: tuple[np.ndarray, np.ndarray] | None) -> _Rows:
    """One pass over the program's primitives at every point (a column each); over the
    whole box (the independents and readings over their intervals: one column) if `points`
    is None."""
    base_lo, base_hi = box if box is not None else (prog.slots.lo, prog.slots.hi)
    if points is None:
        return _pass(prog, np.stack([base_lo, base_hi], axis=1), 1, False, (base_lo, base_hi),
                     np.ones(1, dtype=bool))
    ind = independents(prog)
    k = len(points)
    lo, hi = base_lo, base_hi
    if np.any(points < lo[ind]) or np.any(points > hi[ind]):
        raise ValueError("the point lies outside the search domains")
    # the domains too are rounded outward: a point on a float bound may lie outside the
    # declared (exact) domain, and proves nothing
    dlo, dhi = exact_inside(lo[ind], hi[ind])
    in_domain = np.all(points >= dlo, axis=1) & np.all(points <= dhi, axis=1)
    at = reading_slots(prog)
    rlo, rhi = exact_inside(lo[at], hi[at])  # the slots' bounds are rounded outward
    # a reading a few ulps wide may hold no float of its exact interval: it keeps its
    # enclosure, and the proof then holds for each of its values
    some = rlo <= rhi
    values = (np.broadcast_to(0.5 * lo[at] + 0.5 * hi[at], (k, len(at))) if readings is None
              else readings)
    if np.any(~(values[:, some] >= rlo[some])) or np.any(~(values[:, some] <= rhi[some])):
        raise ValueError("a reading lies outside its interval")
    # one column per point (one point: plain vectors, as fast as before batching)
    def col(v: np.ndarray) -> np.ndarray:
        return v.reshape(-1, k) if k > 1 else v.reshape(-1)

    # each slot's two ends side by side (lo, hi: views): a gather over a large program
    # misses the cache once per slot, not once per end
    both = np.stack([lo, hi], axis=1) if k == 1 else \
        np.repeat(np.stack([lo, hi], axis=1)[:, :, None], k, axis=2)
    lo, hi = both[:, 0], both[:, 1]
    lo[ind], hi[ind] = col(points.T), col(points.T)
    lo[at[some]] = hi[at[some]] = col(values[:, some].T)
    return _pass(prog, both, k, owners, (base_lo, base_hi), in_domain)


def _pass(prog: Program, both: np.ndarray, k: int, owners: bool,
          base: tuple[np.ndarray, np.ndarray], in_domain: np.ndarray) -> _Rows:
    """The pass itself: `both` each slot's two ends (a column per point), the unknowns and
    readings set; `base` the slots' own bounds."""
    lay = definitions(prog)
    at = reading_slots(prog)
    base_lo, base_hi = base

    def col(v: np.ndarray) -> np.ndarray:
        return v.reshape(-1, k) if k > 1 else v.reshape(-1)

    lo, hi = both[:, 0], both[:, 1]
    lo[lay.temp], hi[lay.temp] = -np.inf, np.inf
    caps = lay.temp & (np.isfinite(base_lo) | np.isfinite(base_hi))
    own = np.full(len(lo), NONE, dtype=np.int64)  # the configuration whose readings it uses
    if owners and len(at) and prog.slots.cell_row is not None:
        own[at] = prog.slots.cell_row[at]
    slots, clo, chi, owners_of = [], [], [], []
    for g, mask in zip(prog.groups, lay.defining, strict=True):
        # (np.take: a gather several times faster than indexing, the same values)
        args = [(ends[:, 0].reshape(-1), ends[:, 1].reshape(-1))
                for ends in (np.take(both, c, axis=0) for c in g.args.T)]
        param = None if g.param is None else np.repeat(g.param, k)
        row_own = _combine(np.where(g.args.T >= 0, own[g.args.T], NONE)) if owners else None
        for j, op in enumerate(OUTPUTS.get(g.op, (g.op,))):
            flo, fhi = (col(v) for v in forward(op, args, param))
            out, d = g.out[:, j], mask[:, j]
            if d.all():  # (most groups define every output: no masked copies)
                lo[out], hi[out] = flo, fhi
            else:
                defined = out[d]
                lo[defined], hi[defined] = flo[d], fhi[d]
            if row_own is not None:
                own[out[d]] = row_own[d]
                owners_of.append(_combine(np.stack([row_own[~d], own[out[~d]]])))
            slots.append(out[~d])
            clo.append(flo[~d])
            chi.append(fhi[~d])
    capped = np.flatnonzero(caps)  # a bounded temporary: its value within its bounds
    slots.append(capped)
    clo.append(lo[capped])
    chi.append(hi[capped])
    owners_of.append(own[capped])
    s = np.concatenate(slots)
    tlo, thi = exact_inside(base_lo[s], base_hi[s])
    computed = lay.temp[s] & ~caps[s]  # two computed sides: provable only as points
    found = np.concatenate(owners_of) if owners else None
    a, b = (np.concatenate(c).reshape(len(s), k) for c in (clo, chi))
    lo, hi = lo.reshape(len(lo), k), hi.reshape(len(hi), k)
    # the other side: the exact interval's inside, or the computed slot's value at each point
    tlo, thi = np.repeat(tlo[:, None], k, axis=1), np.repeat(thi[:, None], k, axis=1)
    tlo[computed], thi[computed] = lo[s[computed]], hi[s[computed]]
    return _Rows(s, a, b, tlo, thi, computed, found, in_domain, [len(x) for x in slots])


def _verdicts(prog: Program, r: _Rows) -> list[PointCheck]:
    # an implied equality (the others prove it: ir/primitives.Slots.implied) needs no proof
    implied = np.isin(r.s, np.fromiter(prog.slots.implied, dtype=np.int64))
    return [_verdict(r.s, (r.a[:, i], r.b[:, i]), (r.tlo[:, i], r.thi[:, i]),
                     (r.computed, implied), r.owners, bool(r.in_domain[i]))
            for i in range(r.a.shape[1])]


def _verdict(s: np.ndarray, side: tuple[np.ndarray, np.ndarray],
             target: tuple[np.ndarray, np.ndarray], kinds: tuple[np.ndarray, np.ndarray],
             owners: np.ndarray | None, in_domain: bool) -> PointCheck:
    """One point's check: each row's computed side [a, b] against the other side [tlo, thi]
    (the exact interval's inside of a measured or bounded slot; a computed slot's value at
    the point); `kinds`: the rows comparing two computed sides, and those of them implied by
    the others (they hold where the others do)."""
    (a, b), (tlo, thi), (computed, implied) = side, target, kinds
    with np.errstate(invalid="ignore"):
        excess = np.maximum(np.maximum(b - thi, tlo - a), 0.0)
        ok = (a >= tlo) & (b <= thi)
        ok[computed] &= (tlo[computed] == thi[computed])
        ok[implied] = True
    excess = np.where(np.isnan(excess), np.inf, excess)
    return PointCheck(bool(np.all(ok)) and in_domain, s, a, b, excess, ok, computed,
                      (tlo, thi), owners, in_domain)


def _combine(owners: np.ndarray) -> np.ndarray:
    """Per column of `owners` (one row per argument): the one configuration they use, NONE
    or MIXED (relax/ownership.py)."""
    return reduce(combine, owners, np.full(owners.shape[1], NONE, dtype=np.int64))


# How far the float bounds of a domain may lie outside its exact interval, relative to the
# bounds' magnitude. A measured value y +- e is built from a decimal's enclosure, a unit factor
# and an outward sum: a few ulps of max(|y|, e) <= max(|lo|, |hi|), so the bound may be many
# # ulps of itself away when y - e cancels (2.572364330291748 - 2: 4 ulps of 0.57). 2^-40 is
# a thousand times those few ulps; it costs the inner bounds 1e-12 of their magnitude (an
# interval narrower than that, 1.8 +- 1e-12, holds no surely-inside float: a reading keeps
# its enclosure, a measured side cannot be certified).
ROUNDING_SPAN = 2.0**-40


def exact_inside(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """An interval inside the exact one that [lo, hi] encloses after outward rounding (in by
    ROUNDING_SPAN of the bounds' magnitude and two ulps; a point stays a point; empty, lo >
    hi, when no float is surely inside)."""
    point = lo == hi
    with np.errstate(invalid="ignore"):
        span = ROUNDING_SPAN * np.fmax(np.abs(lo), np.abs(hi))
        span = np.where(np.isfinite(span), span, 0.0)
    a = np.nextafter(np.nextafter(lo + span, np.inf), np.inf)
    b = np.nextafter(np.nextafter(hi - span, -np.inf), -np.inf)
    return np.where(point, lo, a), np.where(point, hi, b)
