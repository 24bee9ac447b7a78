"""Second-order Taylor models and their arithmetic, rounded outward.

A model of a quantity over the box p = c + w t, t in [-1, 1]^n, is a polynomial in t of degree
2 with float coefficients plus a remainder radius r (see taylor.py). Every operation here
truncates its product terms to degree 2 and bounds what it drops, and every floating-point
rounding of a coefficient goes into r, so a model's enclosure holds in exact arithmetic.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from calib_dsl.arith.interval import LIB_ABS, LIB_REL
from calib_dsl.arith.projections import forward

U = 2.0**-53  # unit roundoff


# an upper bound on a float sum of nonnegative terms (<= 2^12 of them, plus products):
# relative error below 2^12 U = 2^-41; 2^-40 covers it
_SUM = 1.0 + 2.0**-40


_TINY = 1e-300  # covers underflow of the (few) products in one remainder update


# Operations given a model of degree 0 (their range over the box, no unknown's term): sound
# and loose; an orientation's angles (elaborate/orientation.py) are such rows, and a program
# holding them keeps the second-order models of its other rows
ENCLOSED = {"sqrt", "atan2"}
SUPPORTED = {"neg", "add", "sub", "mul", "sqr", "sin", "cos", "rot"} | ENCLOSED


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
            kept = (up(np.abs(self.c1).sum(axis=1)), up(np.abs(self.c2).sum(axis=1)))
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


def up(x: np.ndarray) -> np.ndarray:
    """An upper bound on a float expression of nonnegative terms (sums and products)."""
    return x * _SUM + _TINY


def linear_size(a: Models) -> np.ndarray:
    return a.sizes()[0]


def quadratic_size(a: Models) -> np.ndarray:
    return a.sizes()[1]


def size(a: Models) -> np.ndarray:
    """An upper bound on |polynomial part| over the t-box (every monomial is within [-1, 1])."""
    la, qa = a.sizes()
    return up(np.abs(a.c0) + la + qa)


def constant(lo: np.ndarray, hi: np.ndarray, n: int, p: int) -> Models:
    """Models of interval constants [lo, hi] (midpoint, radius); unbounded gives r = inf."""
    k = len(lo)
    with np.errstate(invalid="ignore", over="ignore"):
        mid = 0.5 * lo + 0.5 * hi
        rad = np.maximum(hi - mid, mid - lo)
    ok = np.isfinite(mid) & np.isfinite(rad)
    mid = np.where(ok, mid, 0.0)
    r = np.where(ok, up(rad + np.abs(mid) * 2 * U), np.inf)  # both differences round
    return Models(mid, np.zeros((k, n)), np.zeros((k, p)), r)


def neg(a: Models) -> Models:
    return Models(-a.c0, -a.c1, -a.c2, a.r)


def add(a: Models, b: Models, sign: float = 1.0) -> Models:
    """a + b (or a - b): each coefficient's rounding is at most U times its two terms."""
    r = up(a.r + b.r + 2 * U * (size(a) + size(b)))
    return Models(a.c0 + sign * b.c0, a.c1 + sign * b.c1, a.c2 + sign * b.c2, r)


def scale(a: Models, k: np.ndarray) -> Models:
    """k a for float factors k (one per model)."""
    ak = np.abs(k)
    r = up(ak * a.r + U * ak * size(a))
    return Models(k * a.c0, k[:, None] * a.c1, k[:, None] * a.c2, r)


def shift(a: Models, k: np.ndarray) -> Models:
    """a + k for float constants k."""
    c0 = a.c0 + k
    return Models(c0, a.c1, a.c2, up(a.r + U * (np.abs(a.c0) + np.abs(k))))


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
    r = up(dropped + a.r * sb + b.r * sa + a.r * b.r + 5 * U * sa * sb
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
    In robot models the squares (from the cosines of the angles) carry most of the
    curvature."""
    sq = b2[:, pairs.squares]
    gain = a1 * (0.5 * sq.sum(axis=1)[:, None] + 0.25 * sq)
    mag_a = np.abs(a1)
    mag_sq = np.abs(sq)
    off = np.abs(b2[:, pairs.others]).sum(axis=1)
    la = mag_a.sum(axis=1)
    bound = 0.5 * la * mag_sq.sum(axis=1) - 0.25 * (mag_a * mag_sq).sum(axis=1) + la * off
    # the gain's own rounding (a product and two sums per coefficient) is within 4U of the
    # magnitudes la * sum|b_jj|, which the caller adds
    return gain, up(np.maximum(bound, 0.0) + 2.0**-40 * la * (mag_sq.sum(axis=1) + off))


def _sincos(a: Models, pairs: Pairs) -> tuple[Models, Models]:
    """sin a and cos a. With x0 = a's constant term and d = a - x0 (|d| <= delta):
    sin(x0 + d) = s + c d - s d^2 / 2 + R,  cos(x0 + d) = c - s d - c d^2 / 2 + R',
    |R|, |R'| <= delta^3 / 6 (every derivative of sin is within [-1, 1]); s, c are the library's
    values, a few ulps off (LIB_REL, LIB_ABS), which costs at most that times (1 + delta +
    delta^2 / 2) more."""
    x0 = a.c0
    d = Models(np.zeros_like(x0), a.c1, a.c2, a.r)
    delta = up(linear_size(a) + quadratic_size(a) + a.r)
    dd = mul(d, d, pairs)
    s, c = np.sin(x0), np.cos(x0)
    extra = up(delta**3 / 6.0 + 2 * (LIB_REL + LIB_ABS) * (1.0 + delta + 0.5 * delta**2)) * 1.01
    sin = shift(add(scale(d, c), scale(dd, -0.5 * s)), s)
    cos = shift(add(scale(d, -s), scale(dd, -0.5 * c)), c)
    sin.r = up(sin.r + extra)
    cos.r = up(cos.r + extra)
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
    if op in ENCLOSED:
        return [_range_model(op, args)]
    raise ValueError(f"no Taylor model for primitive {op!r}")


def _range_model(op: str, args: list[Models]) -> Models:
    """The operation's enclosure over the arguments' ranges, as a model of degree 0."""
    ranges = []
    for a in args:
        la, qa = a.sizes()
        spread = up(la + qa + a.r)
        ranges.append((np.nextafter(a.c0 - spread, -np.inf), np.nextafter(a.c0 + spread, np.inf)))
    lo, hi = forward(op, ranges)
    n, p = args[0].c1.shape[1], args[0].c2.shape[1]
    return constant(np.asarray(lo, dtype=float), np.asarray(hi, dtype=float), n, p)
