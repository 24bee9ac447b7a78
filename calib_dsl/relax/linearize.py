"""A linear relaxation of the whole program on the current box (centered / mean-value form).

Every constraint of the program is, after decomposition, "a primitive's output equals a slot
that is already known some other way": a measurement constant, a declared unknown, or a
temporary computed earlier. Writing each side as a function of the declared unknowns p, the
mean-value theorem on the box [p] gives

    f(p) in f(p^) + G (p - p^),   G an interval enclosure of the gradient over the box,

so every solution satisfies two linear inequalities in p. G is the *mixed* (Hansen) form:
its column j encloses the derivative in p_j over the box in which the unknowns before j keep
their ranges and those after j sit at the center (f(p) - f(p^) telescopes one unknown at a
time, so the form holds as well); each column sees about half the box, and the relaxation's
slack on the RX90 is about half the plain form's. The coefficients are the midpoints of G;
the radii of G, the width of f(p^) (it holds the data's uncertainty, folded in instead of one
LP variable per measured joint angle) and every rounding error go into the right-hand sides.
Gradients are propagated forward through the flat program with the same grouping as the
propagator, in interval arithmetic over the *whole* box (not the contracted temporaries: the
mean-value theorem needs the derivative along segments that leave the solution set).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_dsl.arith import interval as iv
from calib_dsl.arith.projections import forward
from calib_dsl.ir.program import Group, Program, derived
from calib_dsl.relax.relaxation import RHS_REL, LinearRelaxation, Rows

Iv = tuple[np.ndarray, np.ndarray]


def independents(prog: Program) -> np.ndarray:
    """The slots of the declared unknowns: the LP's variables."""
    s = prog.slots
    return np.array(sorted({i for i in s.declared if s.kinds[i] in ("param", "var")}),
                    dtype=np.int64)


def group_unknowns(prog: Program, ind: np.ndarray) -> list[np.ndarray]:
    """For each group, the unknowns (column numbers) that some argument of it depends on."""
    n = len(ind)
    dep = np.zeros((len(prog.slots.names), n), dtype=bool)
    dep[ind, np.arange(n)] = True
    out = []
    for g in prog.groups:
        rows = np.zeros((g.out.shape[0], n), dtype=bool)
        for col in g.args.T:
            rows |= dep[col]
        for j in range(g.out.shape[1]):
            dep[g.out[:, j]] |= rows
        out.append(np.flatnonzero(rows.any(axis=0)))
    return out


@dataclass
class Layout:
    """What every forward pass over a program needs, whatever the box: worked out once per
    program (the tight strategy relaxes the same program dozens of times)."""

    ind: np.ndarray  # the declared unknowns' slots
    temp: np.ndarray  # bool per slot
    const: np.ndarray
    defining: list[np.ndarray]  # _defining_masks
    used: list[np.ndarray]  # group_unknowns
    # The passes keep their per-slot arrays of rows (gradients) in this row order: each
    # group's defining outputs take the next rows, so a group stores its results as one
    # slice (a fancy store cost a fifth of a relaxation); the other slots come last.
    pos: np.ndarray  # the row of each slot
    order: np.ndarray  # the slot of each row
    blocks: list[list[tuple[int, int]]]  # per group and output: its defining rows' slice
    # per group and argument column: its rows, and the (rows, used unknowns) mesh
    # (np.ix_ costs as much as a small copy)
    args: list[list[np.ndarray]]
    takes: list[list[tuple]]


def layout(prog: Program, ind: np.ndarray | None = None) -> Layout:
    """The program's layout for the unknowns `ind` (its declared unknowns if None; made once
    per program for those, anew for others)."""
    mine = independents(prog)
    if ind is not None and not np.array_equal(ind, mine):
        return _layout(prog, ind)
    return derived(prog, "layout", lambda: _layout(prog, mine))


def _layout(prog: Program, ind: np.ndarray) -> Layout:
    kinds = np.array(prog.slots.kinds)
    temp = kinds == "temp"
    defining = _defining_masks(prog, temp)
    used = group_unknowns(prog, ind)
    first: list[np.ndarray] = []
    blocks: list[list[tuple[int, int]]] = []
    at = 0
    for g, m in zip(prog.groups, defining, strict=True):
        blocks.append([])
        for j in range(g.out.shape[1]):
            out = g.out[m[:, j], j]  # (no repeats: a slot is defined once)
            first.append(out)
            blocks[-1].append((at, at + len(out)))
            at += len(out)
    placed = np.concatenate([np.zeros(0, np.int64), *first]).astype(np.int64)
    rest = np.setdiff1d(np.arange(len(kinds)), placed)
    order = np.concatenate([placed, rest])
    pos = np.empty(len(kinds), dtype=np.int64)
    pos[order] = np.arange(len(kinds))
    args = [[pos[c] for c in g.args.T] for g in prog.groups]
    takes = [[np.ix_(r, u) for r in rows] for rows, u in zip(args, used, strict=True)]
    return Layout(ind, temp, kinds == "const", defining, used, pos, order, blocks, args,
                  takes)


def measured_cells(prog: Program) -> int:
    """How many LP columns `relax` with cell_variables may need: the measured values with an
    error (one column each at most; fewer when no row uses one)."""
    s = prog.slots
    return int(np.sum(_cells(prog, np.array(s.kinds) == "const", s.lo, s.hi)))


def _cells(prog: Program, const: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The slots that are measured values with an error (an LP column each, at most)."""
    rows = prog.slots.cell_row
    if rows is None:
        return np.zeros(len(lo), dtype=bool)
    return (rows >= 0) & const & (hi > lo) & np.isfinite(lo) & np.isfinite(hi)


def relax(prog: Program, lo: np.ndarray, hi: np.ndarray, cell_variables: bool = True,
          max_cell_columns: int | None = None) -> LinearRelaxation | None:
    """Valid inequalities A x <= b over the box [lo, hi]; x = (p, dq).

    p are the declared unknowns (the first `main` columns). With `cell_variables`, each
    measured value's error dq of one configuration is an LP variable too (bounded by its
    tolerance), so the rows of a configuration share it, as they should; without, each row
    bounds it alone (folded into the right-hand side: fewer columns, a little looser). Over
    `max_cell_columns` such columns, they are folded anyway (the LP would grow too large).
    """
    ind = independents(prog)
    plo, phi = lo[ind], hi[ind]
    if len(ind) == 0 or not (np.all(np.isfinite(plo)) and np.all(np.isfinite(phi))):
        return None
    center = 0.5 * (plo + phi)
    ev = _Evaluation(prog, lo, hi, ind, center, mixed=True)
    rows = ev.run()
    if not rows:
        return None
    return _inequalities(rows, center, plo, phi, ev.e, cell_variables, max_cell_columns)


class _Evaluation:
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
        self.chain = _chain_point if point else _chain
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
        self.G = [np.zeros((n, k)), np.zeros((n, k))]
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

    def _init_cells(self, lo: np.ndarray, hi: np.ndarray) -> None:
        s = self.prog.slots
        n = len(lo)
        rows = s.cell_row if s.cell_row is not None else np.full(n, -1)
        cols = s.cell_col if s.cell_col is not None else np.full(n, -1)
        cell = _cells(self.prog, self.const, lo, hi)
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
        self.D = [np.zeros((n, ncol)), np.zeros((n, ncol))]
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
                            self.rows.append((*_take(form, pick), slots[pick], flag))
        self._capped_temporaries()
        return [self._difference(*r) for r in self.rows]

    def _group(self, g: Group, used: np.ndarray, rows: list[np.ndarray],
               takes: list[tuple]) -> list[tuple]:
        """(F, C, G, D, owner, FM) of each output of the group's primitives. `used`: the
        unknowns (columns of G) some argument depends on; every other column of the outputs'
        G is 0, and only these are computed (a quarter to a half of them on the RX90).
        `rows`: each argument column's rows, `takes` its (rows, used) mesh."""
        cols = list(g.args.T)
        owner, fold = _owners([self.owner[c] for c in cols])
        fa = [(self.F[0][c], self.F[1][c]) for c in cols]
        ca = [self._center(c, f) for c, f in zip(cols, fold, strict=True)]
        every = len(used) == self.G[0].shape[1]
        ga = [(self.G[0][r], self.G[1][r]) if every else (self.G[0][at], self.G[1][at])
              for r, at in zip(rows, takes, strict=True)]
        da = [_zero_rows((self.D[0][r], self.D[1][r]), f) for r, f in zip(rows, fold, strict=True)]
        centers = [forward(op, ca, g.param) for op in _OUTPUTS.get(g.op, (g.op,))]
        signs = _LINEAR.get(g.op) if self.chain is _chain else None
        if signs is not None:  # partials +-1: the chain rule is a signed sum, no product
            f = forward(g.op, fa, g.param)
            m = None
            if self.FM is not None:
                fm = [(self.FM[0][r].ravel(), self.FM[1][r].ravel()) for r in rows]
                lo, hi = forward(g.op, fm)
                shape = (len(rows[0]), self.FM[0].shape[1])
                m = lo.reshape(shape), hi.reshape(shape)
            return [(f, centers[0], _signed_sum(signs, ga), _signed_sum(signs, da), owner, m)]
        parts, ranges = _local(g.op, fa, g.param)
        gparts: list[list[Iv]] = parts
        mixed: list[Iv] | list[None] = [None] * len(ranges)
        if self.FM is not None:  # the same, over each column's box
            fm = [(self.FM[0][r], self.FM[1][r]) for r in rows]
            gparts, mixed = _local_2d(g, fm)
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
        spread = _spread(dl, dh, self.e)
        lo, hi = lo.copy(), hi.copy()
        lo[fold] = lo[fold] - spread
        hi[fold] = hi[fold] + spread
        return _widen(lo, hi)

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
        if len(used) == self.G[0].shape[1]:
            self.G[0][at], self.G[1][at] = rows(gr[0]), rows(gr[1])
        else:
            self.G[0][at, used], self.G[1][at, used] = rows(gr[0]), rows(gr[1])
        self.D[0][at], self.D[1][at] = rows(dd[0]), rows(dd[1])
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
                _flat("sub", gr, (self.G[0][self.pos[slots]], self.G[1][self.pos[slots]])),
                (zero, zero), np.full(len(slots), -1))

    def _fold(self, c: Iv, dd: Iv) -> Iv:
        if dd[0].shape[1] == 0:
            return c
        spread = _spread(dd[0], dd[1], self.e)
        return _widen(c[0] - spread, c[1] + spread)


def _take(form: tuple, pick: np.ndarray) -> tuple:
    f, c, gr, dd, owner = form[:5]
    return tuple((x[0][pick], x[1][pick]) for x in (f, c, gr, dd)) + (owner[pick],)


def _owners(owners: list[np.ndarray]) -> tuple[np.ndarray, list[np.ndarray]]:
    """The configuration an output depends on, and which arguments must fold their cell
    errors first because they come from different configurations."""
    out = np.full(len(owners[0]), -1)
    for o in owners:
        out = np.maximum(out, o)
    mixed = np.zeros(len(out), dtype=bool)
    for o in owners:
        mixed |= (o >= 0) & (o != out)
    fold = [mixed & (o >= 0) for o in owners]
    return np.where(mixed, -1, out), fold


def _zero_rows(d: Iv, rows: np.ndarray) -> Iv:
    if not np.any(rows):
        return d
    lo, hi = d[0].copy(), d[1].copy()
    lo[rows], hi[rows] = 0.0, 0.0
    return lo, hi


def _spread(dl: np.ndarray, dh: np.ndarray, e: np.ndarray) -> np.ndarray:
    """An upper bound on |D (q - q^)| for |q - q^| <= e, rounding included."""
    mag = np.maximum(np.abs(dl), np.abs(dh))
    return (mag @ e) * (1 + 4 * RHS_REL) + 1e-300


def _widen(lo: np.ndarray, hi: np.ndarray) -> Iv:
    return np.nextafter(lo, -np.inf), np.nextafter(hi, np.inf)


def _chain_point(partials: list[Iv], grads: list[Iv]) -> Iv:
    """`_chain` at a point: midpoints in floats (for analysis, not for a guarantee)."""
    total = sum(0.5 * (d[0] + d[1])[:, None] * gi[0] for d, gi in zip(partials, grads,
                                                                      strict=True))
    assert isinstance(total, np.ndarray)
    return total, total


def _chain(partials: list[Iv], grads: list[Iv]) -> Iv:
    """Sum over arguments of partial derivative times the argument's gradient (a partial is
    one interval per row, or one per row and column in the mixed form).

    Half of a relaxation's time is here, on (rows, unknowns) arrays whose entries are mostly
    exact zeros (a slot depends on a quarter of the unknowns), so the product is written out
    rather than taken from `forward`: neither factor is ever empty (ranges of a non-empty
    box), and where either factor is exactly [0, 0] the product is exactly 0, whatever the
    other (as `forward`'s gives too: 0 times a bounded or an unbounded partial). Elsewhere
    the corner products are rounded outward as in interval.mul (a bound that comes out 0
    there is widened by the smallest subnormal, where interval.mul keeps it exact: sound)."""
    total: Iv | None = None
    with iv.quiet():
        for d, g in zip(partials, grads, strict=True):
            dl, dh = d if d[0].ndim == 2 else (d[0][:, None], d[1][:, None])
            gl, gh = g
            p1, p2, p3, p4 = dl * gl, dl * gh, dh * gl, dh * gh
            lo = iv.dn1(np.fmin(np.fmin(p1, p2), np.fmin(p3, p4)))
            hi = iv.up1(np.fmax(np.fmax(p1, p2), np.fmax(p3, p4)))
            zero = ((gl == 0) & (gh == 0)) | ((dl == 0) & (dh == 0))
            np.copyto(lo, 0.0, where=zero)
            np.copyto(hi, 0.0, where=zero)
            total = (lo, hi) if total is None else iv.add(total, (lo, hi))
    assert total is not None
    return total


def _defining_masks(prog: Program, temp: np.ndarray) -> list[np.ndarray]:
    """Per group, (rows, outputs) bool: which rows define their output temporary (its first
    output in program order); the others are constraints."""
    defined = np.zeros(len(temp), dtype=bool)
    masks = []
    for g in prog.groups:
        m = np.zeros(g.out.shape, dtype=bool)
        for j in range(g.out.shape[1]):
            col = g.out[:, j]
            _, first = np.unique(col, return_index=True)
            firsts = np.zeros(len(col), dtype=bool)
            firsts[first] = True
            m[:, j] = temp[col] & ~defined[col] & firsts
            defined[col[m[:, j]]] = True
        masks.append(m)
    return masks


_OUTPUTS = {"rot": ("rotu", "rotv")}  # primitives with more than one output
# The primitives whose partial derivatives are exactly +1 or -1: the signs, per argument.
_LINEAR = {"add": (1.0, 1.0), "sub": (1.0, -1.0), "neg": (-1.0,)}


def _signed_sum(signs: tuple[float, ...], grads: list[Iv]) -> Iv:
    """The chain rule for partials of exactly +-1: the gradients' signed sum (a product by
    +-1 is exact; only the sum rounds, outward, and a sum of exact zeros stays 0)."""
    total: Iv | None = None
    with iv.quiet():
        for sign, g in zip(signs, grads, strict=True):
            term = g if sign > 0 else (-g[1], -g[0])
            total = term if total is None else iv.add(total, term)
    assert total is not None
    return total


def _local(op: str, fa: list[Iv], param: np.ndarray | None) -> tuple[list[list[Iv]], list[Iv]]:
    """Per output of a group's primitives: the partial derivatives over the argument
    ranges fa, and the output's range."""
    if op == "rot":
        return _rotation_partials(fa), [forward(o, fa) for o in _OUTPUTS["rot"]]
    f = forward(op, fa, param)
    return [_partials(op, fa, f, param)], [f]


def _local_2d(g: Group, fa: list[Iv]) -> tuple[list[list[Iv]], list[Iv]]:
    """`_local` on (rows, columns) ranges: flattened, and shaped back."""
    shape = fa[0][0].shape
    flat = [(a[0].ravel(), a[1].ravel()) for a in fa]
    param = None if g.param is None else np.repeat(g.param, shape[1])
    parts, values = _local(g.op, flat, param)

    def back(x: Iv) -> Iv:
        return x[0].reshape(shape), x[1].reshape(shape)

    return [[back(p) for p in ps] for ps in parts], [back(v) for v in values]


def _rotation_partials(fa: list[Iv]) -> list[list[Iv]]:
    """u2 = u cos b - v sin b: (-v2, cos b, -sin b);  v2 = u sin b + v cos b: (u2, sin b, cos b)."""
    b = fa[0]
    cb, sb = forward("cos", [b]), forward("sin", [b])
    u2, v2 = forward("rotu", fa), forward("rotv", fa)
    return [[forward("neg", [v2]), cb, forward("neg", [sb])], [u2, sb, cb]]


def _partials(op: str, a: list[Iv], out: Iv, param: np.ndarray | None) -> list[Iv]:
    """Interval enclosures of the partial derivatives over the argument boxes."""
    n = len(a[0][0])
    one = (np.ones(n), np.ones(n))

    def k(x: float) -> Iv:
        return (np.full(n, x), np.full(n, x))

    if op == "add":
        return [one, one]
    if op == "sub":
        return [one, k(-1.0)]
    if op == "neg":
        return [k(-1.0)]
    if op == "mul":
        return [a[1], a[0]]
    if op == "div":
        inv = forward("div", [one, a[1]])
        return [inv, forward("neg", [forward("div", [a[0], forward("sqr", [a[1]])])])]
    if op == "sqr":
        return [forward("mul", [k(2.0), a[0]])]
    if op == "pow":
        assert param is not None
        return [forward("mul", [(param, param), forward("pow", [a[0]], param - 1)])]
    if op == "sqrt":
        return [forward("div", [one, forward("mul", [k(2.0), out])])]
    if op == "exp":
        return [out]
    if op == "log":
        return [forward("div", [one, a[0]])]
    if op == "sin":
        return [forward("cos", a)]
    if op == "cos":
        return [forward("neg", [forward("sin", a)])]
    if op == "tan":
        return [forward("add", [one, forward("sqr", [out])])]
    if op == "abs":  # the subdifferential where the box touches 0
        lo = np.where(a[0][0] > 0, 1.0, -1.0)
        hi = np.where(a[0][1] < 0, -1.0, 1.0)
        return [(lo, hi)]
    if op == "atan2":  # atan2(y, x): d/dy = x / (x^2 + y^2), d/dx = -y / (x^2 + y^2)
        r2 = forward("add", [forward("sqr", [a[0]]), forward("sqr", [a[1]])])
        dy, dx = forward("div", [a[1], r2]), forward("neg", [forward("div", [a[0], r2])])
        # Across the branch cut (y = 0, x < 0) atan2 jumps by 2 pi: no mean-value form
        # holds there, so those rows get infinite coefficients and are dropped.
        cut = (a[1][0] < 0) & (a[0][0] <= 0) & (a[0][1] >= 0)
        free = (np.where(cut, -np.inf, dy[0]), np.where(cut, np.inf, dy[1]))
        return [free, (np.where(cut, -np.inf, dx[0]), np.where(cut, np.inf, dx[1]))]
    raise ValueError(f"no derivative for {op}")


def _flat(op: str, x: Iv, y: Iv) -> Iv:
    """An elementwise interval operation on broadcast 2-D arrays."""
    xl, xh, yl, yh = np.broadcast_arrays(x[0], x[1], y[0], y[1])
    shape = xl.shape
    lo, hi = forward(op, [(xl.ravel(), xh.ravel()), (yl.ravel(), yh.ravel())])
    return lo.reshape(shape), hi.reshape(shape)


def _inequalities(rows: list, center: np.ndarray, plo: np.ndarray, phi: np.ndarray,
                  e: np.ndarray, cell_variables: bool,
                  max_cell_columns: int | None = None) -> LinearRelaxation:
    """0 in D + H (p - p^) + Q dq  with  |p - p^| <= w, |dq| <= e  gives a two-sided row:
    -D_hi - slack + h.p^ <= h.p + q.dq <= -D_lo + slack + h.p^, where h, q are midpoints and
    the slack bounds the radii times w and e (and every rounding)."""
    dlo, dhi = (np.concatenate([r[0][i] for r in rows]) for i in (0, 1))
    hlo, hhi = (np.concatenate([r[1][i] for r in rows]) for i in (0, 1))
    qlo, qhi = (np.concatenate([r[2][i] for r in rows]) for i in (0, 1))
    owner = np.concatenate([r[3] for r in rows])
    with np.errstate(invalid="ignore"):
        h, hrad = _mid_rad(hlo, hhi)
        q, qrad = _mid_rad(qlo, qhi)
    # a row with an unbounded coefficient says nothing: make it drop out (b = +inf)
    bad = ~(np.all(np.isfinite(h), axis=1) & np.all(np.isfinite(q), axis=1))
    h[bad], q[bad], hrad[bad] = 0.0, 0.0, np.inf
    w = np.maximum(center - plo, phi - center) * (1 + 4 * RHS_REL)
    slack = hrad @ w + qrad @ e
    folded = np.abs(q) @ e
    share = _remainder_share(slack, folded + 0.5 * (dhi - dlo))
    curvature = _curvature(hrad @ w, np.abs(h) @ w)
    if cell_variables and max_cell_columns is not None and q.shape[1]:
        used = np.unique((owner[:, None] * q.shape[1] + np.arange(q.shape[1]))[
            (q != 0) & (owner[:, None] >= 0)])
        cell_variables = len(used) <= max_cell_columns
    if not cell_variables:
        slack = slack + folded  # each row bounds the cell errors alone
        q = q[:, :0]
    hc = h @ center
    err = RHS_REL * (hrad @ w + qrad @ e + folded + np.abs(h) @ np.abs(center)
                  + np.abs(dlo) + np.abs(dhi) + np.abs(hc)) + 1e-300
    b_up = -dlo + slack + hc + err
    b_dn = dhi + slack - hc + err
    (rows_, cols_, vals), xlo, xhi, cells = _cell_columns(q, owner, e)
    A = Rows.join(h, rows_, cols_, vals, len(xlo))
    # one two-sided row per constraint: -b_dn <= h.p + q.dq <= b_up
    b_lo = -b_dn
    keep = np.flatnonzero((np.isfinite(b_up) | np.isfinite(b_lo)) & (A.row_nonzeros() > 0))
    return LinearRelaxation(A.take(keep), b_up[keep], np.concatenate([plo, xlo]),
                            np.concatenate([phi, xhi]), main=len(plo), cells=cells,
                            b_lo=b_lo[keep], remainder_share=share, curvature=curvature,
                            keys=keep, family="first order",
                            col_keys=np.concatenate([np.arange(len(plo)),
                                                     len(plo) + cells[:, 0] * q.shape[1]
                                                     + cells[:, 1]]))


def _remainder_share(remainder: np.ndarray, data: np.ndarray) -> float:
    with np.errstate(invalid="ignore", divide="ignore"):
        r = remainder / (remainder + data)
    r = r[np.isfinite(r)]
    return float(np.percentile(r, 90)) if len(r) else 1.0


def _curvature(remainder: np.ndarray, first_order: np.ndarray) -> float:
    with np.errstate(invalid="ignore", divide="ignore"):
        r = remainder / first_order
    r = r[np.isfinite(r)]
    return float(np.median(r)) if len(r) else 0.0


def _mid_rad(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Midpoint and a radius covering [lo, hi] around it (rounding included)."""
    mid = 0.5 * (lo + hi)
    rad = np.maximum(mid - lo, hi - mid) * (1 + 4 * RHS_REL) + 1e-300
    return mid, rad


def _cell_columns(q: np.ndarray, owner: np.ndarray, e: np.ndarray):
    """One LP column per (configuration, table column) that some row uses: q's midpoints
    scattered into those columns (as row, column, value triples); bounds +- e; and which cell
    each column is (ids as in `Slots.cell_row` / `Slots.cell_col`)."""
    m, k = q.shape
    rows, cols = np.nonzero((q != 0) & (owner[:, None] >= 0))
    if k == 0 or len(rows) == 0:
        none = np.zeros(0, dtype=np.int64)
        return (none, none, np.zeros(0)), np.zeros(0), np.zeros(0), np.zeros((0, 2), np.int64)
    key = owner[rows] * k + cols
    uniq, col = np.unique(key, return_inverse=True)
    bound = e[uniq % k]
    return (rows, col, q[rows, cols]), -bound, bound, np.stack([uniq // k, uniq % k], axis=1)


def constraint_jacobian(prog: Program, point: np.ndarray, lo: np.ndarray | None = None,
                        hi: np.ndarray | None = None) -> np.ndarray:
    """The Jacobian (midpoints) of every constraint row w.r.t. the declared unknowns at a point.

    Rows are the program's constraints in the order `relax` builds them; columns follow
    `independents(prog)`. For identifiability: no guarantee is claimed from it.
    """
    ind = independents(prog)
    blo = prog.slots.lo.copy() if lo is None else lo.copy()
    bhi = prog.slots.hi.copy() if hi is None else hi.copy()
    blo[ind], bhi[ind] = point, point
    rows = _Evaluation(prog, blo, bhi, ind, np.asarray(point, dtype=float), point=True).run()
    if not rows:
        return np.zeros((0, len(ind)))
    return np.concatenate([0.5 * (r[1][0] + r[1][1]) for r in rows])
