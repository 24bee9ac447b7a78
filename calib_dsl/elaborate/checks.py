"""Small shared helpers of the elaborator: exact numbers to floats, the shapes of values,
and the checks whose messages several statements share.
"""

from __future__ import annotations

import math
from fractions import Fraction

from calib_dsl.arith.exact import enclose_fraction
from calib_dsl.elaborate.scope import BUILTINS, Scalar, Value
from calib_dsl.frontend import ast
from calib_dsl.frontend.diagnostics import CalError, Loc

INF = math.inf


ARITH_OPS = {"+": "add", "-": "sub", "*": "mul", "/": "div"}


OP_NAMES = {"add": "the sum", "sub": "the difference", "mul": "the product",
             "div": "the quotient", "neg": "the opposite", "pow": "the power"}


MAX_POW_BITS = 1 << 16  # exact rational powers up to this size; beyond, interval arithmetic


MAX_UNROLL = 10_000_000  # loop iterations / family elements: a guard against typos


# -- helpers ----------------------------------------------------------------------------------
def enclose(q: Fraction, loc: Loc | None) -> tuple[float, float]:
    """The tightest float interval holding the exact rational q."""
    try:
        return enclose_fraction(q)
    except OverflowError:
        raise CalError("number too large for a float", loc) from None


def nearest(q: Fraction, loc: Loc | None) -> float:
    try:
        return q.numerator / q.denominator  # correctly rounded
    except OverflowError:
        raise CalError("number too large for a float", loc) from None


def pairs(a: Value, b: Value, verb: str, loc: Loc) -> list[tuple[Scalar, Scalar]]:
    """Scalar with scalar, or vectors of equal length element by element."""
    if isinstance(a, tuple) and isinstance(b, tuple):
        if len(a) != len(b):
            raise CalError(f"cannot {verb} a {len(a)}-vector and a {len(b)}-vector", loc)
        return list(zip(a, b, strict=True))
    if isinstance(a, tuple) or isinstance(b, tuple):
        raise CalError(f"cannot {verb} {kind_of(a)} and {kind_of(b)}", loc)
    return [(a, b)]


def kind_of(v: Value) -> str:
    return f"a {len(v)}-vector" if isinstance(v, tuple) else "a number"


def count(n: int, noun: str) -> str:
    return f"{n} {noun}" + ("" if n == 1 else "s")


def show(exact: Fraction | None, x: float) -> str:
    return str(exact) if exact is not None else repr(x)


def check_arity(e: ast.Call, n: int, what: str) -> None:
    if len(e.args) != n:
        raise CalError(f"{what} '{e.func}' takes {count(n, 'argument')}, got {len(e.args)}",
                       e.loc)


def check_params(idents: tuple[ast.Ident, ...], what: str) -> None:
    seen: dict[str, Loc] = {}
    for i in idents:
        if i.id in BUILTINS:
            raise CalError(f"'{i.id}' is a built-in function: choose another name", i.loc)
        if i.id in seen:
            raise CalError(f"duplicate {what} '{i.id}' (first at {seen[i.id]})", i.loc)
        seen[i.id] = i.loc


def check_entries(frame: ast.FrameDecl, allowed: tuple[str, ...]) -> None:
    seen: set[str] = set()
    for entry in frame.entries:
        name = entry.name.id
        if name not in allowed:
            extra = (" (a modified-DH base frame has alpha = d = 0; or give the base as x, y, z, "
                     "rx, ry, rz)") if frame.kind == "base" and "theta" in allowed else ""
            raise CalError(f"a {frame.kind} frame has entries {', '.join(allowed)}, not "
                           f"'{name}'{extra}", entry.name.loc)
        if name in seen:
            raise CalError(f"entry '{name}' given twice", entry.name.loc)
        seen.add(name)
