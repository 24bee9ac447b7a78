"""Splitting: cut an unknown the solve left wide into pieces, refine each, keep their hull.

A parameter that is not identifiable alone keeps its whole domain (the RX90's r2 and r3 when
solved in the original unknowns: only r2 + r3 is seen), and a first-order relaxation pays,
in every row, its width times how much its coefficient varies over the box. On a quarter of
r2's domain r3 follows (r3 = (r2 + r3) - r2), both are four times narrower, and so is that
slack. The pieces cover the box, so their hull holds every solution in it; each piece starts
from the unsplit result (near its own fixed point: a few rounds). Nothing is cut unless a
piece's relaxation is narrower than the whole box's (`worth_splitting`).

After shaving (inner/shave.py), an unknown can still be loose (its result much wider than its
certified inner interval) because another one kept its whole domain: the data barely see it
(a tool point near a joint's axis leaves that joint's angle offsets unseen), every
relaxation's remainder grows with its width, and a slice of the loose unknown is relaxed over
that width as the whole box was. `split_loose` cuts such an unknown in halves and contracts
each with the fine rounds a slice gets; the result is the hull of the halves.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from calib_dsl.analysis.identify import analyse_design
from calib_dsl.ir.program import Program
from calib_dsl.ir.status import Stop
from calib_dsl.lp.certify import Certificates
from calib_dsl.relax.layout import independents
from calib_dsl.relax.linearize import relax
from calib_dsl.settings import Settings
from calib_dsl.strategy.cluster import ClusterPieces, cluster_pieces
from calib_dsl.strategy.contractor import Composable, Outcome, Propagation, Sequence, Work
from calib_dsl.strategy.rounds import LPRounds
from calib_dsl.strategy.workers import Children
from calib_dsl.strategy.working import WorkingRows


@dataclass(frozen=True)
class Split(Composable):
    """The split as a contractor: the box unchanged when nothing is worth cutting."""

    prog: Program
    settings: Settings
    certs: Certificates
    tol: float
    max_sweeps: int
    uncut: np.ndarray | None = None  # slots never cut (members left free by reparametrize)
    name: str = "split"

    def with_budget(self, sweeps: int) -> Split:
        return replace(self, max_sweeps=sweeps)

    def contract(self, lo: np.ndarray, hi: np.ndarray) -> Outcome:
        s = self.settings
        # the children that would refine the pieces start while the cut is chosen (their
        # start-up overlaps worth_splitting's relaxations)
        wide = np.any(_left(self.prog, _cuttable(self.prog, self.uncut), lo, hi) > s.left_wide)
        children = cluster_pieces() or (Children(min(s.piece_processes, s.split_pieces),
                                                  __name__)
                                         if s.piece_processes > 1 and wide else None)
        try:
            slot = worth_splitting(self.prog, lo, hi, s, self.uncut)
            if slot is None:
                return Outcome(lo, hi, Stop.NONE)
            refined = _refined(self.prog, pieces(lo, hi, slot, s.split_pieces), self.tol,
                               self.max_sweeps, s, self.certs, children)
        finally:
            if children is not None:
                children.close()
        return _hull(refined, self.prog.slots.names[slot])


def _hull(refined: list[Outcome], name: str) -> Outcome:
    """The hull of the pieces that hold solutions, with the work of all of them."""
    work = Work()
    for piece in refined:
        work = work + piece.work
    boxes = tuple((p.lo, p.hi) for p in refined if not p.empty)
    if not boxes:  # no piece holds a solution: neither does the box
        last = refined[-1]
        return Outcome(last.lo, last.hi, last.stop, work, last.emptied)
    lo = np.min([b[0] for b in boxes], axis=0)
    hi = np.max([b[1] for b in boxes], axis=0)
    return Outcome(lo, hi, Stop.NONE, work, split=(name,), pieces=boxes)


def refine_piece(prog: Program, plo: np.ndarray, phi: np.ndarray, tol: float,
                 max_sweeps: int, s: Settings, certs: Certificates) -> Outcome:
    """One piece of a split box: propagation, then rounds of LPs of its own (starting from the
    whole box's last multipliers and bases), then propagation to the fixed point."""
    steps = (Propagation(prog, max(tol, s.preliminary_tol), max_sweeps)
             & LPRounds(prog, s, certs, tol, max_sweeps, s.split_rounds, second_order=False,
                        cells=True, threads=s.piece_lp_threads)
             & Propagation(prog, tol, max_sweeps))
    return steps.contract(plo, phi)


def _refined(prog: Program, boxes: list[tuple[np.ndarray, np.ndarray]], tol: float,
             max_sweeps: int, s: Settings, certs: Certificates,
             children: Children | ClusterPieces | None = None) -> list[Outcome]:
    """refine_piece of every piece, in order. The pieces are independent, and refining one is
    bound by Python (the first-order relaxations), which threads cannot share out: with two
    cores they go to `children` (child processes, workers.py; the same inputs, so the same
    results, bit for bit). Where children cannot run, the pieces are refined here."""
    args = [(prog, plo, phi, tol, max_sweeps, s, certs.copy()) for plo, phi in boxes]
    done = children.map(refine_piece, args) if children is not None else None
    if done is not None:
        return done
    return [refine_piece(*a) for a in args]


def _cuttable(prog: Program, uncut: np.ndarray | None) -> np.ndarray:
    every = independents(prog)
    return every if uncut is None else every[~np.isin(every, uncut)]


def worth_splitting(prog: Program, lo: np.ndarray, hi: np.ndarray, s: Settings,
                    uncut: np.ndarray | None = None) -> int | None:
    """The unknown to cut, or None: among those not identifiable alone at the middle of the
    search domains that the solve left wider than `left_wide` of their domain (at most
    `split_tried`, the widest first), the one whose middle piece has the narrowest
    relaxation, if that is narrower than the whole box's by `split_worth` of the rows'
    widths (the remainder's share of them); else the pieces would cost their rounds for
    nothing. The slots `uncut` are not candidates."""
    if not np.any(_left(prog, _cuttable(prog, uncut), lo, hi) > s.left_wide):
        return None  # nothing left wide: no need for the analysis (an SVD)
    info = analyse_design(prog, s.rank_tol)
    if info is None:
        return None  # no nominal values, or a Jacobian without finite values there
    every = independents(prog)
    alone = {n for members, _ in info.groups for n in members}
    group = np.array([prog.slots.names[int(k)] in alone for k in every], dtype=bool)
    # a candidate must be wider than every unknown the data pins down (not one known
    # beforehand as well as the data know it, which no split would help)
    pinned = (hi[every] - lo[every])[~group]
    floor = float(pinned.max(initial=0.0))
    ind = every[group & (hi[every] - lo[every] > floor)]
    ind = np.intersect1d(ind, _cuttable(prog, uncut))
    if len(ind) == 0:
        return None
    left = _left(prog, ind, lo, hi)
    tried = [int(ind[k]) for k in np.argsort(-left, kind="stable")[:s.split_tried]
             if left[k] > s.left_wide]
    if not tried:
        return None
    whole = relax(prog, lo, hi, cell_variables=False)
    if whole is None:
        return None
    best, slot = s.split_worth, None
    for k in tried:
        plo, phi = pieces(lo, hi, k, s.split_pieces)[s.split_pieces // 2]
        piece = relax(prog, plo, phi, cell_variables=False)
        if piece is not None and whole.remainder_share - piece.remainder_share > best:
            best, slot = whole.remainder_share - piece.remainder_share, k
    return slot


def _left(prog: Program, slots: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Each slot's width in the box over its search domain (0 where either is not finite)."""
    domain = prog.slots.hi[slots] - prog.slots.lo[slots]
    width = hi[slots] - lo[slots]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(np.isfinite(domain) & (domain > 0) & np.isfinite(width),
                        width / np.where(domain > 0, domain, 1.0), 0.0)


def pieces(lo: np.ndarray, hi: np.ndarray, slot: int,
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


@dataclass(frozen=True)
class Halved:
    """What `split_loose` did: the box (the hull of the halves kept), the unknowns cut."""

    lo: np.ndarray
    hi: np.ndarray
    names: tuple[str, ...]
    work: Work


def split_loose(prog: Program, box: tuple[np.ndarray, np.ndarray],
                inside: tuple[np.ndarray, np.ndarray], s: Settings, budget: float | None,
                tol: float, max_sweeps: int) -> Halved:
    """The box with, while an unknown is loose (wider than `s.loose.above` times its
    certified inner interval, `inside` over `independents(prog)`), an unknown that kept more
    than `s.loose.whole` of its domain cut in halves, each contracted (`contract_fine`), and
    the hull of those not proven empty kept. At most `s.loose.tried` cuts; with `budget`
    (seconds), the next starts only if, at the mean cost of those before, it ends within it
    (the first always starts, unless the budget is 0)."""
    lo, hi = box[0].copy(), box[1].copy()
    ind = independents(prog)
    names: list[str] = []
    work, start = Work(), time.perf_counter()
    if not loose(lo[ind], hi[ind], inside, s.loose.above):
        return Halved(lo, hi, (), work)  # (ranking the unknowns costs relaxations)
    for slot in whole_domains(prog, lo, hi, s):
        if names and not loose(lo[ind], hi[ind], inside, s.loose.above):
            break
        spent = time.perf_counter() - start
        left = max_sweeps - work.sweeps
        if left <= 0 or (budget is not None and (budget <= 0 or (
                names and spent * (1 + 1 / len(names)) > budget))):
            break
        outs = [contract_fine(prog, plo, phi, s, tol, left) for plo, phi in pieces(lo, hi, slot, 2)]
        for out in outs:
            work = work + out.work
        names.append(prog.slots.names[slot])
        kept = [o for o in outs if not o.empty]
        if kept:  # (none kept cannot be with certified points inside: the box stays)
            lo = np.maximum(lo, np.min([o.lo for o in kept], axis=0))
            hi = np.minimum(hi, np.max([o.hi for o in kept], axis=0))
    return Halved(lo, hi, tuple(names), work)


def loose(lo: np.ndarray, hi: np.ndarray, inside: tuple[np.ndarray, np.ndarray],
          above: float) -> bool:
    """Whether some unknown's result is wider than `above` times its certified inner
    interval (the arrays over the unknowns; nan where none is certified)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = (hi - lo) / (inside[1] - inside[0])
    return bool(np.any(np.isfinite(ratio) & (ratio > above)))


def whole_domains(prog: Program, lo: np.ndarray, hi: np.ndarray, s: Settings) -> list[int]:
    """The slots that kept more than `s.loose.whole` of their search domain, at most
    `s.loose.tried`: first those whose halves' first-order relaxations lose the most
    remainder (its share of the rows' widths) against the whole box's, then the widest."""
    every = independents(prog)
    left = _left(prog, every, lo, hi)
    wide = [int(every[k]) for k in np.argsort(-left, kind="stable") if left[k] > s.loose.whole]
    if len(wide) <= 1:
        return wide[:s.loose.tried]
    whole = relax(prog, lo, hi, cell_variables=False)
    if whole is None:
        return wide[:s.loose.tried]
    loss = {}
    for k in wide:
        shares = [r.remainder_share for r in (relax(prog, a, b, cell_variables=False)
                                              for a, b in pieces(lo, hi, k, 2))
                  if r is not None]
        loss[k] = whole.remainder_share - (np.mean(shares) if shares else whole.remainder_share)
    return sorted(wide, key=lambda k: -loss[k])[:s.loose.tried]


def contract_fine(prog: Program, plo: np.ndarray, phi: np.ndarray, s: Settings, tol: float,
                  max_sweeps: int) -> Outcome:
    """A part of a solved box contracted: propagation, then at most `s.shave_rounds` fine
    rounds of LPs over the part alone (on a working set of the rows, grown by the rows their
    optima violate: working.py)."""
    steps = Sequence((
        Propagation(prog, max(tol, s.preliminary_tol), max_sweeps),
        WorkingRows(prog, s, Certificates(), tol, max_sweeps, max_rounds=s.shave_rounds,
                    fine_start=True),
    ), max_sweeps=max_sweeps)
    return steps.contract(plo, phi)
