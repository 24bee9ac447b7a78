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

from dataclasses import dataclass

import numpy as np

from .interval import LIB_ABS, LIB_REL
from .linearize import _defining_masks, group_unknowns, independents
from .program import Program

U = 2.0**-53  # unit roundoff
# an upper bound on a float sum of nonnegative terms (<= 2^12 of them, plus products):
# relative error below 2^12 U = 2^-41; 2^-40 covers it
_SUM = 1.0 + 2.0**-40
_TINY = 1e-300  # covers underflow of the (few) products in one remainder update
SUPPORTED = {"neg", "add", "sub", "mul", "sqr", "sin", "cos", "rot"}
# The models of all slots are held at once (slots x n(n+1)/2 coefficients): above this size
# (the RX90 with 33 unknowns: about 350 configurations) there are no models, and the
# strategies keep to first order rather than exhaust the memory.
MAX_TABLE_BYTES = 600e6


@dataclass
class Models:
    """Taylor models of k slots in n unknowns: c0 (k,), c1 (k, n), c2 (k, P), r (k,)."""

    c0: np.ndarray
    c1: np.ndarray
    c2: np.ndarray
    r: np.ndarray

    def take(self, pick: np.ndarray) -> Models:
        return Models(self.c0[pick], self.c1[pick], self.c2[pick], self.r[pick])


@dataclass
class Pairs:
    """The monomials t_i t_j (i <= j) in a fixed order, and which of them are squares."""

    i: np.ndarray
    j: np.ndarray
    diagonal: np.ndarray  # bool (P,)

    @staticmethod
    def of(n: int) -> Pairs:
        i, j = np.triu_indices(n)
        return Pairs(i, j, i == j)


def _up(x: np.ndarray) -> np.ndarray:
    """An upper bound on a float expression of nonnegative terms (sums and products)."""
    return x * _SUM + _TINY


def linear_size(a: Models) -> np.ndarray:
    return _up(np.abs(a.c1).sum(axis=1))


def quadratic_size(a: Models) -> np.ndarray:
    return _up(np.abs(a.c2).sum(axis=1))


def size(a: Models) -> np.ndarray:
    """An upper bound on |polynomial part| over the t-box (every monomial is within [-1, 1])."""
    return _up(np.abs(a.c0) + linear_size(a) + quadratic_size(a))


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
    cross[:, pairs.diagonal] *= 0.5  # a_i b_i + a_i b_i, halved: exact
    c2 = a.c0[:, None] * b.c2 + b.c0[:, None] * a.c2 + cross
    return Models(c0, c1, c2, r)


def _cubic(a1: np.ndarray, b2: np.ndarray, pairs: Pairs) -> tuple[np.ndarray, np.ndarray]:
    """The cubic terms (a1.t) b2(t) of a product, as a linear part kept and a bound on the rest.

    A square's mean over [-1, 1] is 1/2: t_i t_j^2 = t_i / 2 + t_i (t_j^2 - 1/2) with
    |t_j^2 - 1/2| <= 1/2, and t_i^3 = 3 t_i / 4 + (4 t_i^3 - 3 t_i) / 4 with |4 t^3 - 3 t| <= 1
    (Chebyshev). So the squares of b2 give a1_i (sum_j b_jj / 2 + b_ii / 4) t_i exactly, and
    leave half their bound (a quarter for i = j); the other products t_j t_k leave all of it.
    On the RX90 the squares (from the cosines of the angles) carry most of the curvature."""
    sq = b2[:, pairs.diagonal]
    gain = a1 * (0.5 * sq.sum(axis=1)[:, None] + 0.25 * sq)
    mag_a = np.abs(a1)
    mag_sq = np.abs(sq)
    off = np.abs(b2[:, ~pairs.diagonal]).sum(axis=1)
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
    center = 0.5 * plo + 0.5 * phi
    half = _up(np.maximum(center - plo, phi - center))
    kinds = np.array(prog.slots.kinds)
    temp = kinds == "temp"
    table = constant(np.where(temp, 0.0, lo), np.where(temp, 0.0, hi), n, p)
    table.c0[ind], table.r[ind] = center, 0.0
    table.c1[ind, np.arange(n)] = half
    masks = _defining_masks(prog, temp)
    known = kinds == "const"  # a constraint's target with a range of its own, not a model
    found: list[tuple[Models, np.ndarray, np.ndarray]] = []
    for g, mask, cols in zip(prog.groups, masks.defining, group_unknowns(prog, ind),
                             strict=True):
        # Only the unknowns the group's arguments depend on: every other coefficient of
        # theirs is 0, and so is the result's (a quarter of the work on the RX90).
        at = _pair_index(cols, n)
        local = Pairs.of(len(cols))
        args = [_take_local(table, col, cols, at) for col in g.args.T]
        for j, out in enumerate(apply(g.op, args, local)):
            slots, d = g.out[:, j], mask[:, j]
            _put_local(table, slots[d], out.take(np.flatnonzero(d)), cols, at)
            nd = np.flatnonzero(~d)
            if len(nd):
                whole = _widened(out.take(nd), cols, at, n, p)
                found.append(_constraint(table, whole, slots[nd], known, lo, hi))
    capped = np.flatnonzero(temp & (np.isfinite(prog.slots.lo) | np.isfinite(prog.slots.hi)))
    if len(capped):
        found.append((table.take(capped), lo[capped], hi[capped]))
    if not found:
        return None
    rows = Constraints(_concat([f[0] for f in found]), np.concatenate([f[1] for f in found]),
                np.concatenate([f[2] for f in found]))
    return Expansion(center, half, pairs, rows)


def _pair_index(cols: np.ndarray, n: int) -> np.ndarray:
    """The positions in Pairs.of(n) of the pairs of Pairs.of(len(cols)), mapped by cols."""
    i, j = np.triu_indices(len(cols))
    gi, gj = cols[i], cols[j]
    return gi * n - gi * (gi - 1) // 2 + (gj - gi)


def _take_local(table: Models, rows: np.ndarray, cols: np.ndarray, at: np.ndarray) -> Models:
    return Models(table.c0[rows], table.c1[np.ix_(rows, cols)], table.c2[np.ix_(rows, at)],
                  table.r[rows])


def _put_local(table: Models, slots: np.ndarray, m: Models, cols: np.ndarray,
               at: np.ndarray) -> None:
    """Store models of new slots (their other coefficients are the table's zeros)."""
    table.c0[slots], table.r[slots] = m.c0, m.r
    table.c1[np.ix_(slots, cols)] = m.c1
    table.c2[np.ix_(slots, at)] = m.c2


def _widened(m: Models, cols: np.ndarray, at: np.ndarray, n: int, p: int) -> Models:
    c1, c2 = np.zeros((len(m.c0), n)), np.zeros((len(m.c0), p))
    c1[:, cols], c2[:, at] = m.c1, m.c2
    return Models(m.c0, c1, c2, m.r)


def _put(table: Models, slots: np.ndarray, m: Models) -> None:
    table.c0[slots], table.c1[slots], table.c2[slots], table.r[slots] = m.c0, m.c1, m.c2, m.r


def _constraint(table: Models, f: Models, slots: np.ndarray, known: np.ndarray,
                lo: np.ndarray, hi: np.ndarray) -> tuple[Models, np.ndarray, np.ndarray]:
    """f = s: a constant s (a measured value) is f's target range; an unknown or a temporary
    computed elsewhere gives the row f - s in [0, 0]."""
    other = ~known[slots]
    tlo, thi = lo[slots].copy(), hi[slots].copy()
    if np.any(other):
        k = np.flatnonzero(other)
        diff = add(f.take(k), table.take(slots[k]), -1.0)
        f = Models(f.c0.copy(), f.c1.copy(), f.c2.copy(), f.r.copy())
        _put(f, k, diff)
        tlo[k], thi[k] = 0.0, 0.0
    return f, tlo, thi


def _concat(ms: list[Models]) -> Models:
    return Models(*(np.concatenate([getattr(m, a) for m in ms]) for a in ("c0", "c1", "c2", "r")))
