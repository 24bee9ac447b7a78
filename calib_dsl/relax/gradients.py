"""The interval chain rule: each primitive's partial derivatives over a box, and their
products and sums with the gradients of its arguments, rounded outward.
"""

from __future__ import annotations

import numpy as np

from calib_dsl.arith import interval as iv
from calib_dsl.arith.projections import forward
from calib_dsl.ir.program import Group
from calib_dsl.relax.relaxation import RHS_REL

Iv = tuple[np.ndarray, np.ndarray]


def take(form: tuple, pick: np.ndarray) -> tuple:
    f, c, gr, dd, owner = form[:5]
    return tuple((x[0][pick], x[1][pick]) for x in (f, c, gr, dd)) + (owner[pick],)


def owner_of(owners: list[np.ndarray]) -> tuple[np.ndarray, list[np.ndarray]]:
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


def zero_rows(d: Iv, rows: np.ndarray) -> Iv:
    if not np.any(rows):
        return d
    lo, hi = d[0].copy(), d[1].copy()
    lo[rows], hi[rows] = 0.0, 0.0
    return lo, hi


def fold_spread(dl: np.ndarray, dh: np.ndarray, e: np.ndarray) -> np.ndarray:
    """An upper bound on |D (q - q^)| for |q - q^| <= e, rounding included."""
    mag = np.maximum(np.abs(dl), np.abs(dh))
    return (mag @ e) * (1 + 4 * RHS_REL) + 1e-300


def widen(lo: np.ndarray, hi: np.ndarray) -> Iv:
    return np.nextafter(lo, -np.inf), np.nextafter(hi, np.inf)


def chain_point(partials: list[Iv], grads: list[Iv]) -> Iv:
    """`chain` at a point: midpoints in floats (for analysis, not for a guarantee)."""
    total = sum(0.5 * (d[0] + d[1])[:, None] * gi[0] for d, gi in zip(partials, grads,
                                                                      strict=True))
    assert isinstance(total, np.ndarray)
    return total, total


def chain(partials: list[Iv], grads: list[Iv]) -> Iv:
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


OUTPUTS = {"rot": ("rotu", "rotv")}  # primitives with more than one output


# The primitives whose partial derivatives are exactly +1 or -1: the signs, per argument.
LINEAR = {"add": (1.0, 1.0), "sub": (1.0, -1.0), "neg": (-1.0,)}


def signed_sum(signs: tuple[float, ...], grads: list[Iv]) -> Iv:
    """The chain rule for partials of exactly +-1: the gradients' signed sum (a product by
    +-1 is exact; only the sum rounds, outward, and a sum of exact zeros stays 0)."""
    total: Iv | None = None
    with iv.quiet():
        for sign, g in zip(signs, grads, strict=True):
            term = g if sign > 0 else (-g[1], -g[0])
            total = term if total is None else iv.add(total, term)
    assert total is not None
    return total


def local(op: str, fa: list[Iv], param: np.ndarray | None) -> tuple[list[list[Iv]], list[Iv]]:
    """Per output of a group's primitives: the partial derivatives over the argument
    ranges fa, and the output's range."""
    if op == "rot":
        return _rotation_partials(fa), [forward(o, fa) for o in OUTPUTS["rot"]]
    f = forward(op, fa, param)
    return [_partials(op, fa, f, param)], [f]


def local_2d(g: Group, fa: list[Iv]) -> tuple[list[list[Iv]], list[Iv]]:
    """`local` on (rows, columns) ranges: flattened, and shaped back."""
    shape = fa[0][0].shape
    flat = [(a[0].ravel(), a[1].ravel()) for a in fa]
    param = None if g.param is None else np.repeat(g.param, shape[1])
    parts, values = local(g.op, flat, param)

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


def flat(op: str, x: Iv, y: Iv) -> Iv:
    """An elementwise interval operation on broadcast 2-D arrays."""
    xl, xh, yl, yh = np.broadcast_arrays(x[0], x[1], y[0], y[1])
    shape = xl.shape
    lo, hi = forward(op, [(xl.ravel(), xh.ravel()), (yl.ravel(), yh.ravel())])
    return lo.reshape(shape), hi.reshape(shape)
