"""Gradients of every row of the program with respect to its unknowns, propagated forward
through the flat program over the whole box (the mixed, Hansen form: column j over the box
with the unknowns after j at the center).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from calib_dsl.arith.projections import forward
from calib_dsl.ir.program import Group, Program
from calib_dsl.relax.gradients import (
    LINEAR,
    OUTPUTS,
    Iv,
    chain,
    chain_point,
    flat,
    fold_spread,
    local,
    local_2d,
    owner_of,
    signed_sum,
    take,
    widen,
    zero_rows,
)
from calib_dsl.relax.layout import cells, layout, row_key
from calib_dsl.relax.relaxation import RHS_REL


class Evaluation:
    """One forward pass over the groups, computing for every slot:
    F, its range over the box; C, its value at the center p^ with every measured cell at its
    midpoint; G, its gradient w.r.t. p over the box; D, its gradient w.r.t. the measured cells
    of the one configuration it depends on (`owner`), one column per table column.

    A measurement error dq is folded into a row as |D| e: the rows of one configuration share
    its dq, but each row bounds it alone (no LP variable per measured value). Where a primitive
    mixes two configurations, their D are folded into C first, so columns are never confused.
    """

    def __init__(self, prog: Program, lo: np.ndarray, hi: np.ndarray, ind: np.ndarray,
                 center: np.ndarray, point: bool = False, mixed: bool = False) -> None:
        n, k = len(lo), len(ind)
        self.prog = prog
        # point mode (a Jacobian for analysis, no guarantee): gradients in plain floats
        self.chain = chain_point if point else chain
        self.point = point
        self.layout = layout(prog, ind)
        self.temp, self.const = self.layout.temp, self.layout.const
        self.box = (lo, hi)
        # A temporary's range over the box is recomputed from its definition: the contraction
        # propagation gave it is valid on the solution set only, and the mean-value theorem
        # needs derivatives along whole segments of the box.
        self.F = [np.where(self.temp, -np.inf, lo), np.where(self.temp, np.inf, hi)]
        self.C = [lo.copy(), hi.copy()]
        self.C[0][ind], self.C[1][ind] = center, center
        # G, FM and D are kept by rows in the layout's order (pos: a slot's row)
        self.pos = pos = self.layout.pos
        # (point mode: the gradients are floats, lower and upper ends one array)
        self.G = _pair(np.zeros((n, k)), point)
        self.G[0][pos[ind], np.arange(k)] = 1.0
        self.G[1][pos[ind], np.arange(k)] = 1.0
        self._init_cells(lo, hi)
        # mixed form: FM[:, j] holds every slot's range over the box of column j (unknowns
        # 0..j over their ranges, the later ones at the center; cells over their ranges, so
        # that G holds for every measured value and C, D stay as they are)
        self.FM: list[np.ndarray] | None = None
        if mixed and not point:
            full = np.arange(k)[:, None] <= np.arange(k)[None, :]  # unknown i, column j
            order = self.layout.order
            fm = [np.repeat(f[order][:, None], k, axis=1) for f in self.F]
            fm[0][pos[ind]] = np.where(full, lo[ind][:, None], center[:, None])
            fm[1][pos[ind]] = np.where(full, hi[ind][:, None], center[:, None])
            self.FM = fm
        # (C_f, G_f, D_f, owner_f, target slots, whether the target is the slot's box domain)
        self.rows: list[tuple] = []
        # the argument slots of each row's computed side (-1 past the arity), by rows as in
        # `rows`: which data rows a row depends on (relax/ownership.py)
        self.sources: list[np.ndarray] = []
        self.keys: list[np.ndarray] = []  # each row's row_key, by rows as in `rows`

    def _init_cells(self, lo: np.ndarray, hi: np.ndarray) -> None:
        s = self.prog.slots
        n = len(lo)
        rows = s.cell_row if s.cell_row is not None else np.full(n, -1)
        cols = s.cell_col if s.cell_col is not None else np.full(n, -1)
        cell = cells(self.prog, self.const, lo, hi)
        ncol = int(cols.max()) + 1 if np.any(cell) else 0
        with np.errstate(invalid="ignore", over="ignore"):
            mid = np.where(cell, 0.5 * (lo + hi), 0.0)
        err = np.where(cell, np.maximum(hi - mid, mid - lo), 0.0)
        self.e = np.zeros(ncol)  # per column: a bound on |q - q^| (rounded up)
        if ncol:
            np.maximum.at(self.e, cols[cell], err[cell])
            self.e = self.e * (1 + 4 * RHS_REL) + 1e-300
        self.C[0][cell], self.C[1][cell] = mid[cell], mid[cell]
        self.owner = np.where(cell, rows, -1)
        self.D = _pair(np.zeros((n, ncol)), self.point)
        idx = np.flatnonzero(cell)
        self.D[0][self.pos[idx], cols[idx]] = 1.0
        self.D[1][self.pos[idx], cols[idx]] = 1.0

    def run(self) -> list[tuple[Iv, Iv, Iv, np.ndarray]]:
        lay = self.layout
        for k, (g, mask, used) in enumerate(zip(self.prog.groups, lay.defining, lay.used,
                                                strict=True)):
            for j, form in enumerate(self._group(g, used, lay.args[k], lay.takes[k])):
                slots, d = g.out[:, j], mask[:, j]
                self._store(slots[d], form, d, used, lay.blocks[k][j])
                nd = ~d
                if np.any(nd):
                    form = (*form[:2], self._widened(form[2], used), *form[3:])
                    by_domain = self.const[slots[nd]]
                    for flag in (True, False):
                        pick = np.flatnonzero(nd)[by_domain == flag]
                        if len(pick):
                            self.rows.append((*take(form, pick), slots[pick], flag))
                            self.sources.append(g.args[pick])
                            self.keys.append(row_key(k, j, pick))
        self._capped_temporaries()
        return [self._difference(*r) for r in self.rows]

    def targets(self) -> np.ndarray:
        """After `run`: the slot each row compares with (its measured or bounded side)."""
        return np.concatenate([r[5] for r in self.rows]) if self.rows else np.zeros(0, int)

    def _group(self, g: Group, used: np.ndarray, rows: list[np.ndarray],
               takes: list[tuple]) -> list[tuple]:
        """(F, C, G, D, owner, FM) of each output of the group's primitives. `used`: the
        unknowns (columns of G) some argument depends on; every other column of the outputs'
        G is 0, and only these are computed (in a kinematic chain, far from all of them).
        `rows`: each argument column's rows, `takes` its (rows, used) pair."""
        cols = list(g.args.T)
        owner, fold = owner_of([self.owner[c] for c in cols])
        fa = [(self.F[0][c], self.F[1][c]) for c in cols]
        ca = [self._center(c, f) for c, f in zip(cols, fold, strict=True)]
        every = len(used) == self.G[0].shape[1]
        ga = [_gather(self.G, r if every else at) for r, at in zip(rows, takes, strict=True)]
        da = [zero_rows(_gather(self.D, r), f) for r, f in zip(rows, fold, strict=True)]
        centers = [forward(op, ca, g.param) for op in OUTPUTS.get(g.op, (g.op,))]
        signs = LINEAR.get(g.op) if self.chain is chain else None
        if signs is not None:  # partials +-1: the chain rule is a signed sum, no product
            f = forward(g.op, fa, g.param)
            m = None
            if self.FM is not None:
                fm = [(_taken(self.FM[0], r).ravel(), _taken(self.FM[1], r).ravel()) for r in rows]
                lo, hi = forward(g.op, fm)
                shape = (len(rows[0]), self.FM[0].shape[1])
                m = lo.reshape(shape), hi.reshape(shape)
            return [(f, centers[0], signed_sum(signs, ga), signed_sum(signs, da), owner, m)]
        parts, ranges = local(g.op, fa, g.param)
        gparts: list[list[Iv]] = parts
        mixed: list[Iv] | list[None] = [None] * len(ranges)
        if self.FM is not None:  # the same, over each column's box
            fm = [(_taken(self.FM[0], r), _taken(self.FM[1], r)) for r in rows]
            gparts, mixed = local_2d(g, fm)
            if not every:
                gparts = [[(p[0][:, used], p[1][:, used]) for p in ps] for ps in gparts]
        return [(f, c, self.chain(gp, ga), self.chain(p, da), owner, m)
                for f, c, p, gp, m in zip(ranges, centers, parts, gparts, mixed, strict=True)]

    def _widened(self, gr: Iv, used: np.ndarray) -> Iv:
        """G over the used columns, as G over all (zeros elsewhere)."""
        k = self.G[0].shape[1]
        if len(used) == k:
            return gr
        lo, hi = np.zeros((len(gr[0]), k)), np.zeros((len(gr[0]), k))
        lo[:, used], hi[:, used] = gr
        return lo, hi

    def _center(self, col: np.ndarray, fold: np.ndarray) -> Iv:
        """C of the arguments; where configurations mix, with their cell errors folded in."""
        lo, hi = self.C[0][col], self.C[1][col]
        if not np.any(fold) or self.D[0].shape[1] == 0:
            return lo, hi
        dl, dh = self.D[0][self.pos[col[fold]]], self.D[1][self.pos[col[fold]]]
        spread = fold_spread(dl, dh, self.e)
        lo, hi = lo.copy(), hi.copy()
        lo[fold] = lo[fold] - spread
        hi[fold] = hi[fold] + spread
        return widen(lo, hi)

    def _store(self, slots: np.ndarray, form: tuple, d: np.ndarray, used: np.ndarray,
               block: tuple[int, int]) -> None:
        """The group's outputs on the rows d, to their slots, whose rows are the slice
        `block` (G on the `used` columns: the others stay 0, as a slot is stored once)."""
        f, c, gr, dd, owner, fm = form
        at = slice(*block)
        every = bool(np.all(d))

        def rows(x: np.ndarray) -> np.ndarray:
            return x if every else x[d]

        if fm is not None and self.FM is not None:
            self.FM[0][at], self.FM[1][at] = rows(fm[0]), rows(fm[1])
        self.F[0][slots], self.F[1][slots] = f[0][d], f[1][d]
        self.C[0][slots], self.C[1][slots] = c[0][d], c[1][d]
        one = self.G[1] is self.G[0]  # (point mode: the ends are equal)
        if len(used) == self.G[0].shape[1]:
            self.G[0][at] = rows(gr[0])
            if not one:
                self.G[1][at] = rows(gr[1])
        else:
            self.G[0][at, used] = rows(gr[0])
            if not one:
                self.G[1][at, used] = rows(gr[1])
        self.D[0][at] = rows(dd[0])
        if self.D[1] is not self.D[0]:
            self.D[1][at] = rows(dd[1])
        self.owner[slots] = owner[d]

    def _capped_temporaries(self) -> None:
        """A temporary with a domain of its own (an inequality) is a constraint too."""
        s = self.prog.slots
        capped = np.flatnonzero(self.temp & (np.isfinite(s.lo) | np.isfinite(s.hi)))
        if len(capped):
            r = self.pos[capped]
            form = ((self.F[0][capped], self.F[1][capped]), (self.C[0][capped],
                    self.C[1][capped]), (self.G[0][r], self.G[1][r]),
                    (self.D[0][r], self.D[1][r]), self.owner[capped])
            self.rows.append((*form, capped, True))
            self.sources.append(capped[:, None])  # the capped slot's own value
            self.keys.append(row_key(len(self.prog.groups), 0, capped))

    def _difference(self, f: Iv, c: Iv, gr: Iv, dd: Iv, owner: np.ndarray,
                    slots: np.ndarray, by_domain: bool) -> tuple[Iv, Iv, Iv, np.ndarray]:
        """f - s: the row says 0 is in (C_f - C_s) + (G_f - G_s)(p - p^) + D_f (q - q^)."""
        if by_domain:  # a constant, or a capped temporary: its current box domain
            target = (self.box[0][slots], self.box[1][slots])
            return forward("sub", [c, target]), gr, dd, owner
        # two computed sides: fold both sides' cell errors (rows of this kind are rare)
        c = self._fold(c, dd)
        target = self._fold((self.C[0][slots], self.C[1][slots]),
                            (self.D[0][self.pos[slots]], self.D[1][self.pos[slots]]))
        zero = np.zeros_like(dd[0])
        return (forward("sub", [c, target]),
                flat("sub", gr, (self.G[0][self.pos[slots]], self.G[1][self.pos[slots]])),
                (zero, zero), np.full(len(slots), -1))

    def _fold(self, c: Iv, dd: Iv) -> Iv:
        if dd[0].shape[1] == 0:
            return c
        spread = fold_spread(dd[0], dd[1], self.e)
        return widen(c[0] - spread, c[1] + spread)


def _pair(a: np.ndarray, point: bool) -> list[np.ndarray]:
    """The lower and upper ends of per-slot arrays: one array twice in point mode."""
    return [a, a] if point else [a, np.zeros_like(a)]


def _gather(ends: list[np.ndarray], at: Any) -> Iv:
    """The rows `at` of per-slot arrays (or the block of rows and columns, a pair of index
    arrays): np.take a dimension at a time, the same entries as fancy indexing by a mesh
    at a fraction of its cost."""
    lo = _taken(ends[0], at)
    return (lo, lo) if ends[1] is ends[0] else (lo, _taken(ends[1], at))


def _taken(a: np.ndarray, at: Any) -> np.ndarray:
    if isinstance(at, tuple):
        rows, cols = at
        return np.take(np.take(a, rows, axis=0), cols, axis=1)
    return np.take(a, at, axis=0)
