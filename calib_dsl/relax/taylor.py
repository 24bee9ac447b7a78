"""Second-order Taylor models of every slot of a program over a box (rigorous).

On a wide box the first-order (mean-value) relaxation of `linearize` pays the model's whole
curvature in its right-hand sides; on the RX90's section-4 domains that is a quarter of the
first-order range, and no linear relaxation contracts. A second-order model keeps the
curvature as coefficients and leaves only the third-order terms to a remainder.

Each unknown p_i is written p_i = c_i + w_i t_i with t_i in [-1, 1] (c the box's midpoint, w
its half-width rounded up, so the t-box covers the p-box in exact arithmetic). A *model* of a
slot is a polynomial in t of degree 2 with float coefficients plus a remainder radius r:

    for every t in [-1, 1]^n:   slot value  in  c0 + c1.t + sum_k c2_k m_k(t) + [-r, r]

where m_k(t) = t_i t_j (i <= j). Every operation truncates its product terms to degree 2 and
bounds what it drops (|t_i| <= 1 makes every monomial's magnitude at most 1), and every
floating-point rounding of a coefficient goes into r as well, so the enclosure holds in exact
arithmetic. Models are computed forward through the flat program, one numpy call per group
and operation, like the propagator. Supported primitives: neg, add, sub, mul, sqr, sin, cos,
rot (the matrix and rotation formulations of the robot layer); a program with another
primitive has no model (`None`), and the strategies fall back to first order.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from calib_dsl.arith.interval import LIB_ABS, LIB_REL
from calib_dsl.ir.program import Program, derived
from calib_dsl.relax.layout import Layout, independents, layout

U = 2.0**-53  # unit roundoff
# an upper bound on a float sum of nonnegative terms (<= 2^12 of them, plus products):
# relative error below 2^12 U = 2^-41; 2^-40 covers it
_SUM = 1.0 + 2.0**-40
_TINY = 1e-300  # covers underflow of the (few) products in one remainder update
SUPPORTED = {"neg", "add", "sub", "mul", "sqr", "sin", "cos", "rot"}
# A bound on the models' memory: slots x n(n+1)/2 coefficients (each group keeps its outputs'
# models in the unknowns they depend on only, a quarter of that on the RX90). Above it (the
# RX90 with 33 unknowns: about 350 configurations) there are no models, and the strategies
# keep to first order rather than exhaust the memory.
MAX_TABLE_BYTES = 600e6


@dataclass
class Models:
    """Taylor models of k slots in n unknowns: c0 (k,), c1 (k, n), c2 (k, P), r (k,).
    (Coefficients are not changed in place once their sizes are asked for: they are kept.)"""

    c0: np.ndarray
    c1: np.ndarray
    c2: np.ndarray
    r: np.ndarray

    def take(self, pick: np.ndarray) -> Models:
        return Models(self.c0[pick], self.c1[pick], self.c2[pick], self.r[pick])

    def sizes(self) -> tuple[np.ndarray, np.ndarray]:
        """(linear_size, quadratic_size), computed once: every operation asks for them, some
        twice (a tenth of an expansion)."""
        kept = self.__dict__.get("_sizes")
        if kept is None:
            kept = (_up(np.abs(self.c1).sum(axis=1)), _up(np.abs(self.c2).sum(axis=1)))
            self.__dict__["_sizes"] = kept
        return kept


@dataclass
class Pairs:
    """The monomials t_i t_j (i <= j) in a fixed order, and which of them are squares (as a
    mask, and as the positions of the squares and of the other products)."""

    i: np.ndarray
    j: np.ndarray
    diagonal: np.ndarray  # bool (P,)
    squares: np.ndarray
    others: np.ndarray

    @staticmethod
    def of(n: int) -> Pairs:
        return _pairs(n)


@functools.cache
def _pairs(n: int) -> Pairs:
    """Pairs.of(n), made once per n (every group of every expansion asks; read-only)."""
    i, j = np.triu_indices(n)
    diagonal = i == j
    out = Pairs(i, j, diagonal, np.flatnonzero(diagonal), np.flatnonzero(~diagonal))
    for a in (out.i, out.j, out.diagonal, out.squares, out.others):
        a.setflags(write=False)
    return out


def _up(x: np.ndarray) -> np.ndarray:
    """An upper bound on a float expression of nonnegative terms (sums and products)."""
    return x * _SUM + _TINY


def linear_size(a: Models) -> np.ndarray:
    return a.sizes()[0]


def quadratic_size(a: Models) -> np.ndarray:
    return a.sizes()[1]


def size(a: Models) -> np.ndarray:
    """An upper bound on |polynomial part| over the t-box (every monomial is within [-1, 1])."""
    la, qa = a.sizes()
    return _up(np.abs(a.c0) + la + qa)


# -- arithmetic ---------------------------------------------------------------------------

def constant(lo: np.ndarray, hi: np.ndarray, n: int, p: int) -> Models:
    """Models of interval constants [lo, hi] (midpoint, radius); unbounded gives r = inf."""
    k = len(lo)
    with np.errstate(invalid="ignore", over="ignore"):
        mid = 0.5 * lo + 0.5 * hi
        rad = np.maximum(hi - mid, mid - lo)
    ok = np.isfinite(mid) & np.isfinite(rad)
    mid = np.where(ok, mid, 0.0)
    r = np.where(ok, _up(rad + np.abs(mid) * 2 * U), np.inf)  # both differences round
    return Models(mid, np.zeros((k, n)), np.zeros((k, p)), r)


def neg(a: Models) -> Models:
    return Models(-a.c0, -a.c1, -a.c2, a.r)


def add(a: Models, b: Models, sign: float = 1.0) -> Models:
    """a + b (or a - b): each coefficient's rounding is at most U times its two terms."""
    r = _up(a.r + b.r + 2 * U * (size(a) + size(b)))
    return Models(a.c0 + sign * b.c0, a.c1 + sign * b.c1, a.c2 + sign * b.c2, r)


def scale(a: Models, k: np.ndarray) -> Models:
    """k a for float factors k (one per model)."""
    ak = np.abs(k)
    r = _up(ak * a.r + U * ak * size(a))
    return Models(k * a.c0, k[:, None] * a.c1, k[:, None] * a.c2, r)


def shift(a: Models, k: np.ndarray) -> Models:
    """a + k for float constants k."""
    c0 = a.c0 + k
    return Models(c0, a.c1, a.c2, _up(a.r + U * (np.abs(a.c0) + np.abs(k))))


def mul(a: Models, b: Models, pairs: Pairs) -> Models:
    """a b truncated to degree 2. Dropped: (a1.t) b2 + a2 (b1.t) + a2 b2, bounded by the
    products of sizes; the remainders meet the other factor's whole range. Each coefficient
    sums at most 4 products, so its rounding is within 5U of the sum of their magnitudes, and
    those magnitudes sum over all coefficients to at most size(a) size(b)."""
    la, lb = linear_size(a), linear_size(b)
    qa, qb = quadratic_size(a), quadratic_size(b)
    sa, sb = size(a), size(b)
    gain_a, drop_a = _cubic(a.c1, b.c2, pairs)
    gain_b, drop_b = _cubic(b.c1, a.c2, pairs)
    dropped = drop_a + drop_b + qa * qb
    r = _up(dropped + a.r * sb + b.r * sa + a.r * b.r + 5 * U * sa * sb
            + 4 * U * (la * qb + lb * qa))
    c0 = a.c0 * b.c0
    c1 = a.c0[:, None] * b.c1 + b.c0[:, None] * a.c1 + gain_a + gain_b
    cross = a.c1[:, pairs.i] * b.c1[:, pairs.j] + a.c1[:, pairs.j] * b.c1[:, pairs.i]
    cross[:, pairs.squares] *= 0.5  # a_i b_i + a_i b_i, halved: exact
    c2 = a.c0[:, None] * b.c2 + b.c0[:, None] * a.c2 + cross
    return Models(c0, c1, c2, r)


def _cubic(a1: np.ndarray, b2: np.ndarray, pairs: Pairs) -> tuple[np.ndarray, np.ndarray]:
    """The cubic terms (a1.t) b2(t) of a product, as a linear part kept and a bound on the rest.

    A square's mean over [-1, 1] is 1/2: t_i t_j^2 = t_i / 2 + t_i (t_j^2 - 1/2) with
    |t_j^2 - 1/2| <= 1/2, and t_i^3 = 3 t_i / 4 + (4 t_i^3 - 3 t_i) / 4 with |4 t^3 - 3 t| <= 1
    (Chebyshev). So the squares of b2 give a1_i (sum_j b_jj / 2 + b_ii / 4) t_i exactly, and
    leave half their bound (a quarter for i = j); the other products t_j t_k leave all of it.
    On the RX90 the squares (from the cosines of the angles) carry most of the curvature."""
    sq = b2[:, pairs.squares]
    gain = a1 * (0.5 * sq.sum(axis=1)[:, None] + 0.25 * sq)
    mag_a = np.abs(a1)
    mag_sq = np.abs(sq)
    off = np.abs(b2[:, pairs.others]).sum(axis=1)
    la = mag_a.sum(axis=1)
    bound = 0.5 * la * mag_sq.sum(axis=1) - 0.25 * (mag_a * mag_sq).sum(axis=1) + la * off
    # the gain's own rounding (a product and two sums per coefficient) is within 4U of the
    # magnitudes la * sum|b_jj|, which the caller adds
    return gain, _up(np.maximum(bound, 0.0) + 2.0**-40 * la * (mag_sq.sum(axis=1) + off))


def _sincos(a: Models, pairs: Pairs) -> tuple[Models, Models]:
    """sin a and cos a. With x0 = a's constant term and d = a - x0 (|d| <= delta):
    sin(x0 + d) = s + c d - s d^2 / 2 + R,  cos(x0 + d) = c - s d - c d^2 / 2 + R',
    |R|, |R'| <= delta^3 / 6 (every derivative of sin is within [-1, 1]); s, c are the library's
    values, a few ulps off (LIB_REL, LIB_ABS), which costs at most that times (1 + delta +
    delta^2 / 2) more."""
    x0 = a.c0
    d = Models(np.zeros_like(x0), a.c1, a.c2, a.r)
    delta = _up(linear_size(a) + quadratic_size(a) + a.r)
    dd = mul(d, d, pairs)
    s, c = np.sin(x0), np.cos(x0)
    extra = _up(delta**3 / 6.0 + 2 * (LIB_REL + LIB_ABS) * (1.0 + delta + 0.5 * delta**2)) * 1.01
    sin = shift(add(scale(d, c), scale(dd, -0.5 * s)), s)
    cos = shift(add(scale(d, -s), scale(dd, -0.5 * c)), c)
    sin.r = _up(sin.r + extra)
    cos.r = _up(cos.r + extra)
    return sin, cos


def apply(op: str, args: list[Models], pairs: Pairs) -> list[Models]:
    """The models of a group's outputs (rot has two: u cos b - v sin b, u sin b + v cos b)."""
    if op == "neg":
        return [neg(args[0])]
    if op in ("add", "sub"):
        return [add(args[0], args[1], 1.0 if op == "add" else -1.0)]
    if op == "mul":
        return [mul(args[0], args[1], pairs)]
    if op == "sqr":
        return [mul(args[0], args[0], pairs)]
    if op in ("sin", "cos"):
        s, c = _sincos(args[0], pairs)
        return [s if op == "sin" else c]
    if op == "rot":
        s, c = _sincos(args[0], pairs)
        u, v = args[1], args[2]
        return [add(mul(u, c, pairs), mul(v, s, pairs), -1.0),
                add(mul(u, s, pairs), mul(v, c, pairs))]
    raise ValueError(f"no Taylor model for primitive {op!r}")


# -- the program --------------------------------------------------------------------------

@dataclass
class Constraints:
    """Each constraint row as `model in [lo, hi]`: the row's model and its target interval."""

    models: Models
    lo: np.ndarray
    hi: np.ndarray


@dataclass
class Expansion:
    center: np.ndarray  # c (the unknowns' midpoints)
    half: np.ndarray  # w (half-widths, rounded up): p = c + w t
    pairs: Pairs
    rows: Constraints
    kept: np.ndarray | None = None  # the products given LP columns (set by quadratic.py)


def supported(prog: Program) -> bool:
    return all(g.op in SUPPORTED for g in prog.groups)


def expand(prog: Program, lo: np.ndarray, hi: np.ndarray) -> Expansion | None:
    """Second-order models of every constraint row over the box [lo, hi] (the unknowns'
    entries; the other slots' entries give the constants' and the targets' ranges). None when
    a primitive has no model, an unknown is unbounded, or the models would not fit in
    MAX_TABLE_BYTES."""
    ind = independents(prog)
    if len(ind) == 0 or not supported(prog):
        return None
    plo, phi = lo[ind], hi[ind]
    if not (np.all(np.isfinite(plo)) and np.all(np.isfinite(phi))):
        return None
    n = len(ind)
    pairs = Pairs.of(n)
    p = len(pairs.i)
    if len(lo) * (1 + n + p) * 8 > MAX_TABLE_BYTES:
        return None
    plan = _plan(prog, ind)
    center = 0.5 * plo + 0.5 * phi
    half = _up(np.maximum(center - plo, phi - center))
    temp, known = plan.layout.temp, plan.layout.const
    # every slot's constant term and remainder; the coefficients live with the group that
    # defines the slot (`store`), in that group's own unknowns only
    base = constant(np.where(temp, 0.0, lo), np.where(temp, 0.0, hi), 0, 0)
    c0, r = base.c0, base.r
    c0[ind], r[ind] = center, 0.0
    store: list[list[Models]] = []
    found: list[tuple[Models, np.ndarray, np.ndarray]] = []
    for g, mask, cols, gathers in zip(prog.groups, plan.layout.defining, plan.layout.used,
                                      plan.gathers, strict=True):
        local = Pairs.of(len(cols))
        args = [_gathered(c0, r, store, half, col, len(cols), len(local.i), pieces)
                for col, pieces in zip(g.args.T, gathers, strict=True)]
        outs = apply(g.op, args, local)
        store.append(outs)
        for j, out in enumerate(outs):
            slots, d = g.out[:, j], mask[:, j]
            c0[slots[d]], r[slots[d]] = out.c0[d], out.r[d]
            nd = np.flatnonzero(~d)
            if len(nd):
                whole = _widened(out.take(nd), cols, plan.at[len(store) - 1], n, p)
                others = slots[nd][~known[slots[nd]]]
                models = _global(plan, c0, r, store, half, others, n, p)
                found.append(_constraint(whole, models, slots[nd], known, lo, hi))
    capped = np.flatnonzero(temp & (np.isfinite(prog.slots.lo) | np.isfinite(prog.slots.hi)))
    if len(capped):
        found.append((_global(plan, c0, r, store, half, capped, n, p), lo[capped], hi[capped]))
    if not found:
        return None
    rows = Constraints(_concat([f[0] for f in found]), np.concatenate([f[1] for f in found]),
                np.concatenate([f[2] for f in found]))
    return Expansion(center, half, pairs, rows)


# -- where each slot's model is kept --------------------------------------------------------

@dataclass
class _Piece:
    """The argument rows `rows` of a group whose models some earlier group's output `out`
    defines (at its rows `src`), and where that group's unknowns `c1_at` and pairs `c2_at`
    sit among this group's; `group` < 0: the rows are unknowns, `src` their columns and
    `c1_at` where those sit."""

    rows: np.ndarray
    group: int
    out: int
    src: np.ndarray
    c1_at: np.ndarray
    c2_at: np.ndarray
    # the source's unknowns and pairs that are among this group's (None: all of them); the
    # others are zero in these rows (a row depends on fewer unknowns than its group)
    c1_of: np.ndarray | None
    c2_of: np.ndarray | None
    whole: bool  # every row, in the same unknowns: a plain take

    def __post_init__(self) -> None:
        # the open-mesh index pairs of the gather, made once (np.ix_ costs as much as a
        # small copy, and a plan is used on every box)
        self.to1 = np.ix_(self.rows, self.c1_at)
        self.to2 = np.ix_(self.rows, self.c2_at)
        self.from1 = self.src if self.c1_of is None else np.ix_(self.src, self.c1_of)
        self.from2 = self.src if self.c2_of is None else np.ix_(self.src, self.c2_of)


@dataclass
class _Plan:
    """What expand does on every box of a program, worked out once: the program's layout
    (each group's unknowns and defining rows), each group's pairs, and where each of its
    arguments' models is kept."""

    layout: Layout
    at: list[np.ndarray]  # each group's pairs among all pairs
    gathers: list[list[list[_Piece]]]
    home: tuple[np.ndarray, np.ndarray, np.ndarray]  # (group, output, row) per slot, -1: none
    unknown: np.ndarray  # the column of an unknown's slot, -1 for the others


def _plan(prog: Program, ind: np.ndarray) -> _Plan:
    return derived(prog, "taylor plan", lambda: _make_plan(prog, ind))


def _make_plan(prog: Program, ind: np.ndarray) -> _Plan:
    lay = layout(prog, ind)
    n_slots = len(lay.temp)
    unknown = np.full(n_slots, -1, dtype=np.int64)
    unknown[ind] = np.arange(len(ind))
    hg, hj, hr = (np.full(n_slots, -1, dtype=np.int64) for _ in range(3))
    cols, masks = lay.used, lay.defining
    gathers = []
    for k, g in enumerate(prog.groups):
        gathers.append([_pieces(c, cols[k], cols, (hg, hj, hr), unknown) for c in g.args.T])
        for j in range(g.out.shape[1]):
            d = np.flatnonzero(masks[k][:, j])
            hg[g.out[d, j]], hj[g.out[d, j]], hr[g.out[d, j]] = k, j, d
    return _Plan(lay, [_pair_index(c, len(ind)) for c in cols], gathers, (hg, hj, hr),
                 unknown)


def _pieces(slots: np.ndarray, dest: np.ndarray, cols: list[np.ndarray],
            home: tuple[np.ndarray, np.ndarray, np.ndarray], unknown: np.ndarray,
            done: int | None = None) -> list[_Piece]:
    """How to gather the models of `slots` in the unknowns `dest` (sorted column numbers),
    from the groups before `done` (all if None)."""
    hg, hj, hr = home
    pieces = []
    u = np.flatnonzero(unknown[slots] >= 0)
    if len(u):
        at = np.searchsorted(dest, unknown[slots[u]])
        pieces.append(_Piece(u, -1, -1, unknown[slots[u]], at, np.zeros(0, np.int64), None,
                             None, False))
    g = hg[slots]
    key = np.where((g >= 0) & (g < (len(cols) if done is None else done)),
                   2 * g + hj[slots], -1)
    for k in np.unique(key[key >= 0]):
        rows = np.flatnonzero(key == k)
        src_cols = cols[k // 2]
        c1_of = np.flatnonzero(np.isin(src_cols, dest))
        c1_at = np.searchsorted(dest, src_cols[c1_of])
        c2_at = _pair_index(c1_at, len(dest))
        full = len(c1_of) == len(src_cols)
        # the source's pairs among both members in dest, in the order of _pair_index
        c2_of = None if full else _pair_index(c1_of, len(src_cols))
        whole = len(rows) == len(slots) and full and len(src_cols) == len(dest)
        pieces.append(_Piece(rows, int(k // 2), int(k % 2), hr[slots[rows]], c1_at, c2_at,
                             None if full else c1_of, c2_of, whole))
    return pieces


def _pair_index(cols: np.ndarray, n: int) -> np.ndarray:
    """The positions in Pairs.of(n) of the pairs of Pairs.of(len(cols)), mapped by cols."""
    i, j = np.triu_indices(len(cols))
    gi, gj = cols[i], cols[j]
    return gi * n - gi * (gi - 1) // 2 + (gj - gi)


def _gathered(c0: np.ndarray, r: np.ndarray, store: list[list[Models]], half: np.ndarray,
              slots: np.ndarray, n: int, p: int, pieces: list[_Piece]) -> Models:
    """The models of `slots` in a group's n unknowns and p pairs (zero where a slot has no
    coefficient: a constant, or a temporary no group defines before)."""
    if len(pieces) == 1 and pieces[0].whole:
        s = store[pieces[0].group][pieces[0].out]
        return Models(c0[slots], s.c1[pieces[0].src], s.c2[pieces[0].src], r[slots])
    c1, c2 = np.zeros((len(slots), n)), np.zeros((len(slots), p))
    for pc in pieces:
        if pc.group < 0:
            c1[pc.rows, pc.c1_at] = half[pc.src]
            continue
        s = store[pc.group][pc.out]
        c1[pc.to1] = s.c1[pc.from1]
        c2[pc.to2] = s.c2[pc.from2]
    return Models(c0[slots], c1, c2, r[slots])


def _global(plan: _Plan, c0: np.ndarray, r: np.ndarray, store: list[list[Models]],
            half: np.ndarray, slots: np.ndarray, n: int, p: int) -> Models:
    """The models of `slots` in all the unknowns, as the groups done so far define them."""
    pieces = _pieces(slots, np.arange(n), plan.layout.used, plan.home, plan.unknown,
                     len(store))
    return _gathered(c0, r, store, half, slots, n, p, pieces)


def _widened(m: Models, cols: np.ndarray, at: np.ndarray, n: int, p: int) -> Models:
    c1, c2 = np.zeros((len(m.c0), n)), np.zeros((len(m.c0), p))
    c1[:, cols], c2[:, at] = m.c1, m.c2
    return Models(m.c0, c1, c2, m.r)


def _put(table: Models, slots: np.ndarray, m: Models) -> None:
    table.c0[slots], table.c1[slots], table.c2[slots], table.r[slots] = m.c0, m.c1, m.c2, m.r


def _constraint(f: Models, models: Models, slots: np.ndarray, known: np.ndarray,
                lo: np.ndarray, hi: np.ndarray) -> tuple[Models, np.ndarray, np.ndarray]:
    """f = s: a constant s (a measured value) is f's target range; an unknown or a temporary
    computed elsewhere (`models`: theirs, in order) gives the row f - s in [0, 0]."""
    other = ~known[slots]
    tlo, thi = lo[slots].copy(), hi[slots].copy()
    if np.any(other):
        k = np.flatnonzero(other)
        diff = add(f.take(k), models, -1.0)
        f = Models(f.c0.copy(), f.c1.copy(), f.c2.copy(), f.r.copy())
        _put(f, k, diff)
        tlo[k], thi[k] = 0.0, 0.0
    return f, tlo, thi


def _concat(ms: list[Models]) -> Models:
    return Models(*(np.concatenate([getattr(m, a) for m in ms]) for a in ("c0", "c1", "c2", "r")))
