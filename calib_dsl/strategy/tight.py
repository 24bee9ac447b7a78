"""The `tight` strategy: forward-backward propagation, then a linear relaxation of the whole
system solved by LP, re-linearized on each smaller box, then propagation again.

Propagation first brings the box down to where a first-order model is accurate (the
relaxation's error terms shrink with the square of the box). The LP sees all constraints at
once, which propagation cannot: it reaches the hull of the linearized problem. The first LP
round folds each measurement error into its row (cheap); later rounds give the measured values
of each configuration LP columns of their own, so the rows of one configuration share them.
Every LP bound is certified (lpbound), so the result stays guaranteed. After a round of LPs,
the next rounds first reuse its multipliers on the new, smaller box (the same combination of
the same rows, certified again there: a matrix product instead of an LP), and solve LPs again
only when that stops paying.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from calib_dsl.ir.program import Program
from calib_dsl.lp.lpbound import WORKERS, Certificates, LinearRelaxation, lp_bounds, reused_bounds
from calib_dsl.propagate.fixpoint import Emptied, Result, propagate
from calib_dsl.relax.linearize import independents, measured_cells, relax
from calib_dsl.relax.quadratic import narrowed, relax_quadratic, to_box
from calib_dsl.relax.taylor import Expansion
from calib_dsl.strategy.reparametrize import along_combinations, back
from calib_dsl.strategy.workers import Children

PRELIMINARY_TOL = 1e-2  # propagation before the first relaxation: a small box, not a fixed point
MAX_CELL_COLUMNS = 3000  # beyond, measurement errors stay folded (the LP would grow too large)
STALLED = 1e-3  # an unknown that gained less than this in a folded round sits out the next one
FOLDED_UNTIL = 0.3  # rounds fold the measurement errors while some unknown gains more than this
SETTLED = 0.01  # a relaxation whose remainder is below this share of its rows' widths is final
# Above this curvature (the first-order relaxation's remainder over its first-order range,
# median over rows) first-order rounds stall (about 1/7 on the RX90): rounds use second-order
# models instead (quadratic.py), until the box is small enough.
WIDE = 0.06
WIDE_MIN_GAIN = 0.02  # a second-order round gaining less than this ends the search
# The second-order LPs are dense, and one objective's optimum is far from the next's: the
# interior point method ("ipm") takes 15-20 iterations for any objective, the simplex
# hundreds of pivots, and yet less time in all (section 4, an earlier release: 42 s against
# 53 s for the second-order rounds). Each worker solves both signs of an unknown in a row:
# an objective starts from the optimum of the one solved before it.
# WIDE_OWN_BASES: whether each objective starts instead from its own basis of the last round
# of LPs. Since HiGHS's scaling is off (lpbound.SCALING) that costs more than it saves: the
# box moved much in between (the rounds reusing multipliers), and on section 4 the rounds
# of LPs after the first took 3.2, 4.0 and 1.3 s from their own bases, 2.1, 2.4 and 1.3 s
# from the last optimum, to the same bounds.
WIDE_SOLVER = "simplex"
WIDE_OWN_BASES = False
# After a round of LPs, the next rounds first reuse its multipliers on the new box (a matrix
# product each, Certificates): on the RX90 from section 4 they give nearly the LPs' bounds,
# and the LPs are solved again only when such a round gains less than REUSE_GAIN (4
# second-order rounds of LPs instead of 10); at most REUSE_ROUNDS of them in a row. Since
# each second-order round narrows its own bounds further (_narrowed_bounds), a round gaining
# 5-10 % no longer pays: 0.1 leaves out two of 14 reused rounds on section 4 (and on two
# other data sets, and in the rotation formulation), to the same box widths.
REUSE_GAIN = 0.1
REUSE_ROUNDS = 20
# Probe LPs (lpbound._probe_points) before a second-order round's objectives: they were
# worth it when each objective started from its own basis of the last round; from the
# previous objective's optimum (WIDE_OWN_BASES) they cost more than they save.
WIDE_PROBES = False
NARROWED_ROUNDS = 10  # _narrowed_bounds: at most this many passes per second-order round,
NARROWED_GAIN = 0.01  # while one narrows some unknown by this much
WIDE_ITERATIONS = 20000  # simplex pivots per objective in a second-order round
WIDE_SECONDS = 30.0
# At the end, an unknown not identifiable alone (like the RX90's r2 and r3) and left wider
# than LEFT_WIDE of its search domain is cut into SPLIT_PIECES pieces, each refined by at most
# SPLIT_ROUNDS LP rounds of its own, if a piece's relaxation is narrower than the whole box's
# by SPLIT_WORTH of the rows' widths; SPLIT_TRIED such unknowns are tried, the widest first.
LEFT_WIDE = 0.25
SPLIT_PIECES = 4
SPLIT_ROUNDS = 10
SPLIT_WORTH = 0.03
SPLIT_TRIED = 3
# Child processes that refine the pieces, one per core the LPs use (1: the solving process
# refines them itself), and the LP threads of each: the children share the cores (with 2
# threads each, the pieces of section 4 took 5.5 s, with 1 about 4.5 s). A piece refined in
# the solving process uses as many, for the same result.
PIECE_PROCESSES = WORKERS
PIECE_LP_THREADS = max(1, WORKERS // PIECE_PROCESSES)


def solve_tight(prog: Program, tol: float = 1e-5, max_sweeps: int = 1000,
                max_rounds: int = 40, min_gain: float = 0.1,
                second_order: bool = True, split: bool = True,
                combinations: bool = True) -> Result:
    """_solve, on the program rewritten in unknowns along the identifiable combinations of
    the parameters the data cannot separate (with `combinations`; reparametrize.py): the
    same solutions, a tighter relaxation. The result is a box of `prog`, with the bounds of
    each combination in `combinations`."""
    rep = along_combinations(prog) if combinations else None
    if rep is None:
        return _solve(prog, tol, max_sweeps, max_rounds, min_gain, second_order, split)
    start = time.perf_counter()
    # (the members left as unknowns, like r3, are not cut: the model barely depends on them
    # in the new unknowns, and a piece's relaxation is hardly narrower, 0.021 against 0.027)
    res = _solve(rep.prog, tol, max_sweeps, max_rounds, min_gain, second_order, split,
                 uncut=np.array(rep.free, dtype=np.int64))
    res.combinations = [(text, float(res.lo[s]), float(res.hi[s]))
                        for text, s, _, _ in rep.combinations]
    res.lo, res.hi = back(rep, res.lo, res.hi)
    res.pieces = [back(rep, a, b) for a, b in res.pieces]
    res.seconds = time.perf_counter() - start
    return res


def _solve(prog: Program, tol: float, max_sweeps: int, max_rounds: int, min_gain: float,
           second_order: bool, split: bool, uncut: np.ndarray | None = None) -> Result:
    """Propagate, then alternate certified LP rounds with propagation until a round gains less
    than min_gain (relative width of every unknown), then propagate to the fixed point.

    Each round re-linearizes on the box the previous one left: far from the fixed point the
    first-order model is coarse, and a round gains only part of the way, so rounds repeat as
    long as they pay. While they gain a lot, rows fold the measurement errors (a small LP);
    once they gain less than FOLDED_UNTIL, the errors of each configuration get LP columns of
    their own (the hull of the linearized problem), and the loop stops when such a round gains
    less than min_gain; an unknown that gained less than that in such a round sits out the
    next one (these rounds are the expensive ones, and its bound is already near the hull).
    A round whose relaxation is settled (its remainder below SETTLED of the rows' widths) ends
    its phase: the next relaxation would be the same LP.
    An unknown no round has moved (gain below STALLED every time: on the RX90's Test A, the
    19 parameters known to 1e-5) also sits out the first such round.
    After a second-order or cell round of LPs, the next rounds reuse its multipliers on the
    new box (lpbound.Certificates; the LPs of a folded first-order round cost no more than
    its relaxation) while such a round narrows some unknown by REUSE_GAIN; then a round
    solves its LPs again (a first-order one's simplex starting each objective from its own
    last basis).
    On a box too wide for first order (curvature above WIDE) a round relaxes second-order
    Taylor models instead (quadratic.py); such rounds repeat while they gain WIDE_MIN_GAIN.
    With `split`, an unknown left wide (not identifiable alone) is then cut into pieces, each
    piece refined by LP rounds of its own, and the hull of the pieces returned (_split);
    never one of the slots `uncut`.
    """
    start = time.perf_counter()
    res = propagate(prog, tol=max(tol, PRELIMINARY_TOL), max_sweeps=max_sweeps)
    sweeps = res.sweeps
    certs = Certificates()  # the multipliers (and bases) of the last LPs of each objective
    res, (rounds, reused), more = _lp_rounds(prog, res, tol, max_sweeps, max_rounds,
                                             min_gain, second_order, certs, unsolved=uncut)
    sweeps += more
    if res.status == "contracted":
        res = propagate(prog, tol=tol, max_sweeps=max_sweeps, lo=res.lo, hi=res.hi)
        sweeps += res.sweeps
    if split and res.status == "contracted":
        res, (more_rounds, more_reused), more = _split(prog, res, tol, max_sweeps, min_gain,
                                                       certs, uncut)
        rounds, reused, sweeps = rounds + more_rounds, reused + more_reused, sweeps + more
    res.sweeps = sweeps
    res.rounds = rounds
    res.reused = reused
    res.seconds = time.perf_counter() - start
    return res


def _lp_rounds(prog: Program, res: Result, tol: float, max_sweeps: int, max_rounds: int,
               min_gain: float, second_order: bool, certs: Certificates,
               cells: bool = False, threads: int = WORKERS,
               unsolved: np.ndarray | None = None) -> tuple[Result, tuple[int, int], int]:
    """The LP rounds of solve_tight from the box of `res`: (result, (rounds of LPs, rounds
    of reused multipliers), sweeps). With `cells`, the rounds start with the measurement
    errors as LP columns (a box near the end). `certs` holds the multipliers and bases of the
    LPs solved (updated in place; a piece of a split box starts with its whole box's). The
    slots `unsolved` get no LPs (a member left free by reparametrize: the data do not see
    it, and propagation gives it what its combination allows)."""
    sweeps, rounds = 0, 0
    ind = independents(prog)
    skip = np.zeros(len(ind), dtype=bool)
    never = np.isin(ind, unsolved) if unsolved is not None else skip.copy()  # (no LPs)
    moved = np.zeros(len(ind), dtype=bool)  # whether any round narrowed it by STALLED
    # with too many measured values for cell columns, "cell" rounds fold the errors too
    cellular = measured_cells(prog) <= MAX_CELL_COLUMNS
    reuse, reused = bool(certs.y), 0  # (a piece of a split box: its whole box's multipliers)
    total_reused = 0
    last = ""  # the kind of the last round
    while res.status == "contracted" and rounds < max_rounds:
        lo, hi = res.lo, res.hi
        reuse = reuse and reused < REUSE_ROUNDS
        # the second-order phase ends with a round of LPs (reused multipliers may have left
        # the box just below WIDE while the LPs would still contract it much further)
        ending = second_order and not cells and last == "reused second order"
        if (reuse and certs.family == "second order" and second_order and not cells) \
                or ending:
            rel = None  # a second-order round again: no first-order relaxation needed
        else:
            rel = relax(prog, lo, hi, cell_variables=cells, max_cell_columns=MAX_CELL_COLUMNS)
            if rel is None:
                break
        wide = second_order and not cells and (rel is None or rel.curvature > WIDE)
        quad = relax_quadratic(prog, lo, hi) if wide else None
        if quad is None and rel is None:  # (cannot happen: a first round built them)
            break
        wide = quad is not None  # None: the program has no second-order models
        target = quad[0] if quad is not None else rel
        assert target is not None
        fresh = not (reuse and certs.usable(target))
        skip = skip | never
        if quad is not None:
            tl, th = _bounds(quad[0], len(ind), skip, certs, fresh, threads=threads,
                             iterations=WIDE_ITERATIONS,
                             seconds=WIDE_SECONDS, solver=WIDE_SOLVER, probes=WIDE_PROBES,
                             own_bases=WIDE_OWN_BASES)
            tl, th = _narrowed_bounds(quad[0], quad[1], tl, th, certs)
            nlo, nhi = to_box(quad[1], tl, th)
        else:
            nlo, nhi = _bounds(target, len(ind), skip, certs, fresh, threads=threads)
        new_lo, new_hi = np.maximum(lo[ind], nlo), np.minimum(hi[ind], nhi)
        if np.any(new_lo > new_hi):  # certified bounds cross: no solution at all
            k = int(np.flatnonzero(new_lo > new_hi)[0])
            res = _emptied(prog, res, prog.slots.names[int(ind[k])])
            rounds += fresh
            break
        gains = _gains(hi[ind] - lo[ind], new_hi - new_lo)
        lo, hi = lo.copy(), hi.copy()
        lo[ind], hi[ind] = new_lo, new_hi
        res = propagate(prog, tol=max(tol, PRELIMINARY_TOL), max_sweeps=max_sweeps, lo=lo, hi=hi)
        sweeps += res.sweeps
        best = gains.max(initial=0.0)
        moved |= gains >= STALLED
        last = ("" if fresh else "reused ") + target.family
        if not fresh:  # reused multipliers: again while they pay, else the LPs again
            reused += 1
            total_reused += 1
            reuse = best >= REUSE_GAIN
            continue
        rounds += 1
        # the next round first tries this round's multipliers, unless its LPs are as cheap as
        # a relaxation (folded first-order rounds: as many columns as unknowns), or the
        # second-order phase is over (the box is no longer too wide for first order)
        # (the curvature of a round without a first-order relaxation: the second-order
        # one's estimate of it, quadratic._curvature)
        reuse, reused = cells or (wide and (rel or target).curvature > WIDE), 0
        if wide:
            if best < WIDE_MIN_GAIN:
                break  # neither order contracts this box: the search domains are too wide
            # every unknown in the next one: rounds of LPs are rare between reused rounds,
            # and one that did not move may move after them (section 4: 39 s instead of 48)
            skip = np.zeros_like(skip)
            continue
        # once the model is linear over the box to within a small part of the data's errors,
        # relaxing again gives the same LP: only the cell columns can still gain
        assert rel is not None  # built in every first-order round
        settled = rel.remainder_share < SETTLED
        if cells and (best < min_gain or settled):
            break
        if not cells and settled and not cellular:
            break  # the next round would solve the same LP
        if not cells and (best < FOLDED_UNTIL or settled):
            # a tighter relaxation: every unknown again, but one that no round has moved (a
            # parameter known beforehand)
            cells, skip = True, ~moved
        else:  # a stalled unknown is tried again a round later
            skip = (gains < (min_gain if cells else STALLED)) & ~skip
    return res, (rounds, total_reused), sweeps


def _bounds(rel: LinearRelaxation, n: int, skip: np.ndarray, certs: Certificates,
            fresh: bool, **lp_options: Any) -> tuple[np.ndarray, np.ndarray]:
    """Certified bounds on the relaxation's n main columns: from the multipliers kept in
    `certs` (a matrix product), and unless only those are asked for, from the LPs too (the
    tighter of each pair is kept, and the LPs' multipliers replace the old ones)."""
    lo, hi = reused_bounds(rel, np.eye(n), certs)
    if not fresh:
        return lo, hi
    tl, th = lp_bounds(rel, np.eye(n), skip=skip, certificates=certs, **lp_options)
    return np.maximum(lo, tl), np.minimum(hi, th)


def _narrowed_bounds(rel: LinearRelaxation, ex: Expansion, tl: np.ndarray, th: np.ndarray,
                     certs: Certificates) -> tuple[np.ndarray, np.ndarray]:
    """The bounds [tl, th] of a second-order round, narrowed further with the same
    multipliers: on the relaxation narrowed to them (quadratic.narrowed: its product columns
    bounded by the products of the new bounds) they certify narrower bounds, and so on while
    some unknown narrows by NARROWED_GAIN (at most NARROWED_ROUNDS times; a matrix product
    each, no new expansion). On section 4 the box after the second-order rounds is 2.9x and
    3.7x the hull (median, widest) instead of 3.4x and 8.5x, with 14 reused rounds instead
    of 17."""
    n = rel.main
    for _ in range(NARROWED_ROUNDS):
        if np.any(tl > th):
            break  # no solution: the caller says so
        lo, hi = reused_bounds(narrowed(rel, ex, tl, th), np.eye(n), certs)
        lo, hi = np.maximum(lo, tl), np.minimum(hi, th)
        gain = _gains(th - tl, hi - lo).max(initial=0.0)
        tl, th = lo, hi
        if gain < NARROWED_GAIN:
            break
    return tl, th


def _split(prog: Program, res: Result, tol: float, max_sweeps: int, min_gain: float,
           certs: Certificates, uncut: np.ndarray | None = None
           ) -> tuple[Result, tuple[int, int], int]:
    """Cut an unknown that the solve left wide into pieces, refine each piece by LP rounds,
    and return the hull of the pieces: (result, (rounds of LPs, reused rounds), sweeps).

    A parameter that is not identifiable alone keeps its whole domain (the RX90's r2 and r3:
    only r2 + r3 is seen), and a first-order relaxation pays, in every row, its width times
    how much its coefficient varies over the box: on the RX90 from section 4, widths 1.9-2.6x
    the hull. On a quarter of r2's domain r3 follows (r3 = (r2 + r3) - r2), both are four
    times narrower, and so is that slack. The pieces cover the box, so their hull holds every
    solution in it; each piece starts from the unsplit result (near its own fixed point: a
    few rounds). Nothing is cut unless a piece's relaxation is narrower (_worth_splitting).
    """
    # the children that would refine the pieces start while the cut is chosen (their start-up,
    # 0.3-0.5 s, overlaps _worth_splitting's relaxations)
    every = _cuttable(prog, uncut)
    children = (Children(min(PIECE_PROCESSES, SPLIT_PIECES), __name__)
                if PIECE_PROCESSES > 1 and np.any(_left(prog, every, res.lo, res.hi) > LEFT_WIDE)
                else None)
    try:
        slot = _worth_splitting(prog, res.lo, res.hi, uncut)
        if slot is None:
            return res, (0, 0), 0
        pieces = _pieces(res.lo, res.hi, slot, SPLIT_PIECES)
        refined = _refined(prog, pieces, tol, max_sweeps, min_gain, certs, children)
    finally:
        if children is not None:
            children.close()
    rounds, reused, sweeps = 0, 0, 0
    boxes = []
    last = res
    for piece, n, k, s in refined:
        rounds, reused, sweeps = rounds + n, reused + k, sweeps + s
        last = piece
        if piece.status != "contracted":
            continue  # no solution in this piece
        boxes.append((piece.lo, piece.hi))
    if not boxes:  # no piece holds a solution: neither does the box
        return last, (rounds, reused), sweeps
    lo = np.min([b[0] for b in boxes], axis=0)
    hi = np.max([b[1] for b in boxes], axis=0)
    out = Result("contracted", lo, hi, sweeps, 0.0, res.stop,
                 split=[prog.slots.names[slot]], pieces=boxes)
    return out, (rounds, reused), sweeps


def _refine_piece(prog: Program, plo: np.ndarray, phi: np.ndarray, tol: float,
                  max_sweeps: int, min_gain: float,
                  certs: Certificates) -> tuple[Result, int, int, int]:
    """One piece of a split box: propagation, then LP rounds of its own (starting from the
    whole box's last multipliers and bases), then propagation to the fixed point."""
    piece = propagate(prog, tol=max(tol, PRELIMINARY_TOL), max_sweeps=max_sweeps, lo=plo, hi=phi)
    sweeps = piece.sweeps
    piece, (n, k), s = _lp_rounds(prog, piece, tol, max_sweeps, SPLIT_ROUNDS, min_gain, False,
                                  certs, cells=True, threads=PIECE_LP_THREADS)
    sweeps += s
    if piece.status == "contracted":
        piece = propagate(prog, tol=tol, max_sweeps=max_sweeps, lo=piece.lo, hi=piece.hi)
        sweeps += piece.sweeps
    return piece, n, k, sweeps


def _refined(prog: Program, pieces: list[tuple[np.ndarray, np.ndarray]], tol: float,
             max_sweeps: int, min_gain: float, certs: Certificates,
             children: Children | None = None) -> list[tuple[Result, int, int, int]]:
    """_refine_piece of every piece, in order. The pieces are independent, and refining one
    is bound by Python (the first-order relaxations), which threads cannot share out: with
    two cores they go to `children` (PIECE_PROCESSES child processes, workers.py; the same
    inputs, so the same results, bit for bit). Where children cannot run, the pieces are
    refined here."""
    args = [(prog, plo, phi, tol, max_sweeps, min_gain, certs.copy()) for plo, phi in pieces]
    done = children.map(_refine_piece, args) if children is not None else None
    if done is not None:
        return done
    return [_refine_piece(*a) for a in args]


def _cuttable(prog: Program, uncut: np.ndarray | None) -> np.ndarray:
    every = independents(prog)
    return every if uncut is None else every[~np.isin(every, uncut)]


def _worth_splitting(prog: Program, lo: np.ndarray, hi: np.ndarray,
                     uncut: np.ndarray | None = None) -> int | None:
    """The unknown to cut, or None: among those not identifiable alone at the middle of the
    search domains (identify.py) that the solve left wider than LEFT_WIDE of their domain (at
    most SPLIT_TRIED, the widest first), the one whose middle piece has the narrowest
    relaxation, if that is narrower than the whole box's by SPLIT_WORTH of the rows' widths
    (the remainder's share of them); else the pieces would cost their rounds for nothing.
    (RX90 near its solution: 0.027 against 0.023; from section 4: 0.285 against 0.213.)
    The slots `uncut` are not candidates."""
    from calib_dsl.analysis.identify import analyse_design

    if not np.any(_left(prog, _cuttable(prog, uncut), lo, hi) > LEFT_WIDE):
        return None  # nothing left wide: no need for the analysis (an SVD)
    info = analyse_design(prog)
    if info is None:
        return None  # no nominal values, or a Jacobian without finite values there
    every = independents(prog)
    alone = {n for members, _ in info.groups for n in members}
    group = np.array([prog.slots.names[int(s)] in alone for s in every], dtype=bool)
    # a candidate must be wider than every unknown the data pins down (not one known
    # beforehand to 1e-5, like 19 of Test A's, which no split would help)
    pinned = (hi[every] - lo[every])[~group]
    floor = float(pinned.max(initial=0.0))
    ind = every[group & (hi[every] - lo[every] > floor)]
    ind = np.intersect1d(ind, _cuttable(prog, uncut))
    if len(ind) == 0:
        return None
    left = _left(prog, ind, lo, hi)
    tried = [int(ind[k]) for k in np.argsort(-left, kind="stable")[:SPLIT_TRIED]
             if left[k] > LEFT_WIDE]
    if not tried:
        return None
    whole = relax(prog, lo, hi, cell_variables=False)
    if whole is None:
        return None
    best, slot = SPLIT_WORTH, None
    for s in tried:
        plo, phi = _pieces(lo, hi, s, SPLIT_PIECES)[SPLIT_PIECES // 2]
        piece = relax(prog, plo, phi, cell_variables=False)
        if piece is not None and whole.remainder_share - piece.remainder_share > best:
            best, slot = whole.remainder_share - piece.remainder_share, s
    return slot


def _left(prog: Program, slots: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Each slot's width in the box over its search domain (0 where either is not finite)."""
    domain = prog.slots.hi[slots] - prog.slots.lo[slots]
    width = hi[slots] - lo[slots]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(np.isfinite(domain) & (domain > 0) & np.isfinite(width),
                        width / np.where(domain > 0, domain, 1.0), 0.0)


def _pieces(lo: np.ndarray, hi: np.ndarray, slot: int,
            per: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """The box cut into `per` pieces along one slot. Adjacent pieces share their float
    endpoint, and the first and last keep the box's: together they cover the box."""
    edges = lo[slot] + (hi[slot] - lo[slot]) * np.arange(per + 1) / per
    edges[0], edges[-1] = lo[slot], hi[slot]
    edges = np.maximum.accumulate(np.clip(edges, lo[slot], hi[slot]))
    out = []
    for k in range(per):
        plo, phi = lo.copy(), hi.copy()
        plo[slot], phi[slot] = edges[k], edges[k + 1]
        out.append((plo, phi))
    return out


def _emptied(prog: Program, res: Result, name: str) -> Result:
    return Result("infeasible", res.lo, res.hi, res.sweeps, 0.0, "empty",
                  Emptied(name, None, "the linear relaxation of all constraints together"))


def _gains(before: np.ndarray, after: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(before > 0, (before - after) / np.where(before > 0, before, 1), 0.0)
