"""Forward evaluation and backward projections of the primitive constraints, vectorized:
the operator tables (unary.py, binary.py, the rotation primitive) and their entry points.

``forward(op, args, param)`` encloses { f(x1..xk) : xi in args[i] }, rounded outward.
``backward(op, out, args, param)`` returns, for each argument, a sub-interval of it holding every
value that takes part in a solution of ``out = f(args)`` inside the box (the projection). The
projections are the hull of the exact projection, up to outward rounding, except where noted
(atan2, rotu/rotv): see docs/soundness.md.

Every call costs a bounded number of numpy calls whatever the array length.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from calib_dsl.arith import interval as iv
from calib_dsl.arith.binary import (
    bw_add,
    bw_atan2,
    bw_div,
    bw_mul,
    bw_mul_raw,
    bw_sub,
    fw_add,
    fw_atan2,
    fw_div,
    fw_mul,
    fw_sub,
)
from calib_dsl.arith.boxes import finish_box, prepare_boxes
from calib_dsl.arith.interval import (
    INF,
    Arr,
    Interval,
)
from calib_dsl.arith.rotation import rot_contract_raw
from calib_dsl.arith.unary import (
    bw_abs,
    bw_cos,
    bw_exp,
    bw_log,
    bw_neg,
    bw_pow,
    bw_sin,
    bw_sqr,
    bw_sqrt,
    bw_tan,
    fw_abs,
    fw_cos,
    fw_exp,
    fw_log,
    fw_neg,
    fw_pow,
    fw_sin,
    fw_sqr,
    fw_sqrt,
    fw_tan,
)


def forward(op: str, args: list[Interval], param: Arr | None = None) -> Interval:
    """An outward-rounded enclosure of { f(x1..xk) : xi in args[i] } (elementwise)."""
    fn = FORWARD.get(op)
    if fn is None:
        raise ValueError(f"unknown primitive {op!r}")
    with iv.quiet():
        boxes, e = prepare_boxes(args)
        lo, hi = fn(boxes, param)
        return finish_box((lo, hi), e)


def backward(op: str, out: Interval, args: list[Interval],
             param: Arr | None = None) -> list[Interval]:
    """For each argument, the hull of its values in the solutions of out = f(args) (a
    sub-interval of args[i]); every argument is empty where the box holds no solution."""
    fn = BACKWARD.get(op)
    if fn is None:
        raise ValueError(f"unknown primitive {op!r}")
    with iv.quiet():
        boxes, e = prepare_boxes([out, *args])
        res = fn(boxes[0], boxes[1:], param)
        res = [iv.intersect(r, a) for r, a in zip(res, boxes[1:], strict=True)]
        for r in res:  # no solution for one argument means no solution at all
            re = iv.empty_mask(r)
            e = re if e is None else e | re
        if e is not None and e.any():
            return [(np.where(e, INF, r[0]), np.where(e, -INF, r[1])) for r in res]
        return res


def rot_forward(beta: Interval, u: Interval, v: Interval, which: str) -> Interval:
    """rotu = u cos b - v sin b = rho cos(b + phi), rotv = rho sin(b + phi) with (u, v) =
    rho (cos phi, sin phi). For fixed b the extremes over the (u, v) box are at corners, so the
    exact range is the hull over the 4 corners of rho_c * cos(B + phi_c) (resp. sin): optimal
    up to rounding (a few ulps of rho, phi, cos each). Intersected with the plain interval
    formula, which is tighter for a point-like b (fewer roundings) and the only one used for
    non-finite u, v."""
    c, s = iv.cos(beta), iv.sin(beta)
    if which == "rotu":
        nlo, nhi = iv.sub(iv.mul(u, c), iv.mul(v, s))
    else:
        nlo, nhi = iv.add(iv.mul(u, s), iv.mul(v, c))
    f = iv.cos if which == "rotu" else iv.sin
    us = iv.rows(u[0], u[0], u[1], u[1])
    vs = iv.rows(v[0], v[1], v[0], v[1])
    finite = np.isfinite(us).all(axis=0) & np.isfinite(vs).all(axis=0)
    t = iv.mul(iv.hypot_point(us, vs), f(iv.add(beta, iv.atan2_point(vs, us))))
    lo, hi = np.maximum(t[0].min(axis=0), nlo), np.minimum(t[1].max(axis=0), nhi)
    if finite.all():
        return lo, hi
    return np.where(finite, lo, nlo), np.where(finite, hi, nhi)


def _fw_rotu(a: list[Interval], p: Arr | None) -> Interval:
    return rot_forward(a[0], a[1], a[2], "rotu")


def _fw_rotv(a: list[Interval], p: Arr | None) -> Interval:
    return rot_forward(a[0], a[1], a[2], "rotv")


def _bw_rot(which: str) -> Callable[[Interval, list[Interval], Arr | None], list[Interval]]:
    def bw(z: Interval, a: list[Interval], p: Arr | None) -> list[Interval]:
        # One output alone: the joint rotation contractor with the other output free.
        free = (np.full_like(z[0], -INF), np.full_like(z[0], INF))
        u2, v2 = (z, free) if which == "rotu" else (free, z)
        b, u, v, _, _ = rot_contract_raw(a[0], a[1], a[2], u2, v2)
        return [b, u, v]
    return bw


FORWARD: dict[str, Callable[[list[Interval], Arr | None], Interval]] = {
    "neg": fw_neg, "sqr": fw_sqr, "sqrt": fw_sqrt, "exp": fw_exp, "log": fw_log,
    "sin": fw_sin, "cos": fw_cos, "tan": fw_tan, "abs": fw_abs, "pow": fw_pow,
    "add": fw_add, "sub": fw_sub, "mul": fw_mul, "div": fw_div, "atan2": fw_atan2,
    "rotu": _fw_rotu, "rotv": _fw_rotv,
}


BACKWARD: dict[str, Callable[[Interval, list[Interval], Arr | None], list[Interval]]] = {
    "neg": bw_neg, "sqr": bw_sqr, "sqrt": bw_sqrt, "exp": bw_exp, "log": bw_log,
    "sin": bw_sin, "cos": bw_cos, "tan": bw_tan, "abs": bw_abs, "pow": bw_pow,
    "add": bw_add, "sub": bw_sub, "mul": bw_mul, "div": bw_div, "atan2": bw_atan2,
    "rotu": _bw_rot("rotu"), "rotv": _bw_rot("rotv"),
}


# Raw backward projections for `propagate`'s fast sweep (non-empty inputs, inside quiet(), the
# caller intersects with the arguments): where they differ from BACKWARD, they are faster and
# give the same bounds, element for element.
FAST_BACKWARD: dict[str, Callable[[Interval, list[Interval], Arr | None], list[Interval]]] = {
    "mul": bw_mul_raw,
}
