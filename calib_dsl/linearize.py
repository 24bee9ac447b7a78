"""A linear relaxation of the whole program on the current box (centered / mean-value form).

Every constraint of the program is, after decomposition, "a primitive's output equals a slot
that is already known some other way": a measurement constant, a declared unknown, or a
temporary computed earlier. Writing each side as a function of the declared unknowns p, the
mean-value theorem on the box [p] gives

    f(p) in f(p^) + G (p - p^),   G an interval enclosure of the gradient over the box,

so every solution satisfies two linear inequalities in p. Their coefficients are the
midpoints of G; the radii of G, the width of f(p^) (it holds the data's uncertainty, folded
in instead of one LP variable per measured joint angle) and every rounding error go into the
right-hand sides. Gradients are propagated forward through the flat program with the same
grouping as the propagator, in interval arithmetic over the *whole* box (not the contracted
temporaries: the mean-value theorem needs the derivative along segments that leave the
solution set).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .lpbound import LinearRelaxation
from .program import Group, Program
from .projections import forward

Iv = tuple[np.ndarray, np.ndarray]
_REL = 1e-9  # rounding budget of right-hand sides (see lpbound)


@dataclass
class _Masks:
    """Per group: which rows define their output temporary (the others are constraints)."""

    defining: list[np.ndarray]  # (n, outputs) bool per group


def independents(prog: Program) -> np.ndarray:
    """The slots of the declared unknowns: the LP's variables."""
    s = prog.slots
    return np.array(sorted({i for i in s.declared if s.kinds[i] in ("param", "var")}),
                    dtype=np.int64)


def relax(prog: Program, lo: np.ndarray, hi: np.ndarray) -> LinearRelaxation | None:
    """Valid inequalities A p <= b on the declared unknowns over the box [lo, hi]."""
    ind = independents(prog)
    plo, phi = lo[ind], hi[ind]
    if len(ind) == 0 or not (np.all(np.isfinite(plo)) and np.all(np.isfinite(phi))):
        return None
    center = 0.5 * (plo + phi)
    ev = _Evaluation(prog, lo, hi, ind, center)
    rows = ev.run()
    if not rows:
        return None
    A, b = _inequalities(rows, center, plo, phi)
    return LinearRelaxation(A, b, plo, phi)


class _Evaluation:
    """One forward pass: box range F, value at the center C, gradient G of every slot."""

    def __init__(self, prog: Program, lo: np.ndarray, hi: np.ndarray, ind: np.ndarray,
                 center: np.ndarray) -> None:
        n, k = len(lo), len(ind)
        self.prog = prog
        self.F = [lo.copy(), hi.copy()]
        self.C = [lo.copy(), hi.copy()]
        self.C[0][ind] = center
        self.C[1][ind] = center
        self.G = [np.zeros((n, k)), np.zeros((n, k))]
        self.G[0][ind, np.arange(k)] = 1.0
        self.G[1][ind, np.arange(k)] = 1.0
        kinds = prog.slots.kinds
        temp = np.array([kd == "temp" for kd in kinds], dtype=bool)
        # A temporary's range over the box is recomputed from its definition: forget the
        # contraction propagation gave it (valid only on the solution set).
        self.F[0][temp], self.F[1][temp] = -np.inf, np.inf
        self.masks = _defining_masks(prog, temp)
        self.box = (lo, hi)
        self.const = np.array([kd == "const" for kd in kinds], dtype=bool)
        self.temp = temp
        # (C_f, G_f, target slots, whether the target is the slot's box domain)
        self.rows: list[tuple[Iv, Iv, np.ndarray, bool]] = []

    def run(self) -> list[tuple[Iv, Iv]]:
        for g, mask in zip(self.prog.groups, self.masks.defining, strict=True):
            outs = _group_forms(g, self.F, self.C, self.G)
            for j, (f, c, gr) in enumerate(outs):
                slots, d = g.out[:, j], mask[:, j]
                self._store(slots[d], f, c, gr, d)
                nd = ~d
                if np.any(nd):
                    rows = ((c[0][nd], c[1][nd]), (gr[0][nd], gr[1][nd]))
                    by_domain = self.const[slots[nd]]
                    for flag in (True, False):
                        pick = by_domain == flag
                        if np.any(pick):
                            self.rows.append(((rows[0][0][pick], rows[0][1][pick]),
                                              (rows[1][0][pick], rows[1][1][pick]),
                                              slots[nd][pick], flag))
        self._capped_temporaries()
        return [self._difference(*r) for r in self.rows]

    def _store(self, slots, f, c, gr, d) -> None:
        self.F[0][slots], self.F[1][slots] = f[0][d], f[1][d]
        self.C[0][slots], self.C[1][slots] = c[0][d], c[1][d]
        self.G[0][slots], self.G[1][slots] = gr[0][d], gr[1][d]

    def _capped_temporaries(self) -> None:
        """A temporary with a domain of its own (an inequality) is a constraint too."""
        s = self.prog.slots
        capped = np.flatnonzero(self.temp & (np.isfinite(s.lo) | np.isfinite(s.hi)))
        if len(capped):
            self.rows.append(((self.C[0][capped], self.C[1][capped]),
                              (self.G[0][capped], self.G[1][capped]), capped, True))

    def _difference(self, c: Iv, gr: Iv, slots: np.ndarray, by_domain: bool) -> tuple[Iv, Iv]:
        """f - s: the row says 0 is in (C_f - C_s) + (G_f - G_s)(p - p^)."""
        if by_domain:  # a constant, or a capped temporary: its current box domain
            target = (self.box[0][slots], self.box[1][slots])
            return forward("sub", [c, target]), gr
        target = (self.C[0][slots], self.C[1][slots])
        return forward("sub", [c, target]), _flat("sub", gr, (self.G[0][slots],
                                                               self.G[1][slots]))


def _defining_masks(prog: Program, temp: np.ndarray) -> _Masks:
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
    return _Masks(masks)


def _group_forms(g: Group, F, C, G) -> list[tuple[Iv, Iv, Iv]]:
    """(range over the box, value at the center, gradient) of each output of a group."""
    fa = [(F[0][c], F[1][c]) for c in g.args.T]
    ca = [(C[0][c], C[1][c]) for c in g.args.T]
    ga = [(G[0][c], G[1][c]) for c in g.args.T]
    if g.op == "rot":
        return _rotation_forms(fa, ca, ga)
    f = forward(g.op, fa, g.param)
    c = forward(g.op, ca, g.param)
    grad = None
    for d, gi in zip(_partials(g.op, fa, f, g.param), ga, strict=True):
        term = _flat("mul", (d[0][:, None], d[1][:, None]), gi)
        grad = term if grad is None else _flat("add", grad, term)
    assert grad is not None
    return [(f, c, grad)]


def _rotation_forms(fa, ca, ga) -> list[tuple[Iv, Iv, Iv]]:
    b, u, v = fa
    cb, sb = forward("cos", [b]), forward("sin", [b])
    outs = []
    for op in ("rotu", "rotv"):
        f = forward(op, fa)
        c = forward(op, ca)
        if op == "rotu":  # u2 = u cos b - v sin b: d/db = -v2, d/du = cos b, d/dv = -sin b
            parts = [forward("neg", [forward("rotv", fa)]), cb, forward("neg", [sb])]
        else:  # v2 = u sin b + v cos b: d/db = u2, d/du = sin b, d/dv = cos b
            parts = [forward("rotu", fa), sb, cb]
        grad = None
        for d, gi in zip(parts, ga, strict=True):
            term = _flat("mul", (d[0][:, None], d[1][:, None]), gi)
            grad = term if grad is None else _flat("add", grad, term)
        assert grad is not None
        outs.append((f, c, grad))
    return outs


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
    if op == "abs":
        lo = np.where(a[0][0] >= 0, 1.0, -1.0)
        hi = np.where(a[0][1] <= 0, -1.0, 1.0)
        return [(lo, hi)]
    if op == "atan2":  # atan2(y, x): d/dy = x / (x^2 + y^2), d/dx = -y / (x^2 + y^2)
        r2 = forward("add", [forward("sqr", [a[0]]), forward("sqr", [a[1]])])
        return [forward("div", [a[1], r2]), forward("neg", [forward("div", [a[0], r2])])]
    raise ValueError(f"no derivative for {op}")


def _flat(op: str, x: Iv, y: Iv) -> Iv:
    """An elementwise interval operation on broadcast 2-D arrays."""
    xl, xh, yl, yh = np.broadcast_arrays(x[0], x[1], y[0], y[1])
    shape = xl.shape
    lo, hi = forward(op, [(xl.ravel(), xh.ravel()), (yl.ravel(), yh.ravel())])
    return lo.reshape(shape), hi.reshape(shape)


def _inequalities(rows: list[tuple[Iv, Iv]], center: np.ndarray, plo: np.ndarray,
                  phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """0 in D + H (p - p^)  =>  h.p <= -D_lo + r.w + h.p^  and  -h.p <= D_hi + r.w - h.p^."""
    dlo = np.concatenate([r[0][0] for r in rows])
    dhi = np.concatenate([r[0][1] for r in rows])
    hlo = np.concatenate([r[1][0] for r in rows])
    hhi = np.concatenate([r[1][1] for r in rows])
    h = 0.5 * (hlo + hhi)
    rad = np.maximum(h - hlo, hhi - h)
    rad = rad * (1 + 4 * _REL) + 1e-300  # covers the rounding of the midpoint
    w = np.maximum(center - plo, phi - center) * (1 + 4 * _REL)
    slack = rad @ w
    hc = h @ center
    err = _REL * (np.abs(rad) @ w + np.abs(h) @ np.abs(center) + np.abs(dlo) + np.abs(dhi)
                  + np.abs(slack) + np.abs(hc)) + 1e-300
    b_up = -dlo + slack + hc + err
    b_dn = dhi + slack - hc + err
    A = np.concatenate([h, -h])
    b = np.concatenate([b_up, b_dn])
    keep = np.isfinite(b) & np.all(np.isfinite(A), axis=1) & np.any(A != 0, axis=1)
    return A[keep], b[keep]
