"""Unrolling: a `for` loop's body, or a `sum(k in a..b)`'s term, once per integer of the
range, each in a scope of its own where the index is that integer (exact). Both share the
guard on the iterations in all (nested loops and sums multiplied), checked before any runs.
"""

from __future__ import annotations

from collections.abc import Callable
from fractions import Fraction
from typing import TypeVar

from calib_dsl.elaborate.checks import MAX_UNROLL, pairs
from calib_dsl.elaborate.context import Context
from calib_dsl.elaborate.scope import Scope, Value
from calib_dsl.frontend import ast
from calib_dsl.frontend.diagnostics import CalError, Loc

T = TypeVar("T")


class Loops(Context):
    """`for` statements' and `sum` expressions' iterations."""

    def unrolled(self, var: ast.Ident, rng: ast.Range, scope: Scope, loc: Loc, what: str,
                 body: Callable[[Scope], T]) -> list[T]:
        """body(scope) for each integer k of `rng` (none when its first is above its last),
        with `var` = k in a scope of its own; `what` ("loop", "sum") names the construct in
        messages."""
        lo = self.integer(rng.lo, scope, f"a {what} bound")
        hi = self.integer(rng.hi, scope, f"a {what} bound")
        n = max(hi - lo + 1, 0)
        total = self.loop_product * n
        if total > MAX_UNROLL:
            kind = what if self.loop_product == 1 else \
                "nested loops" if what == "loop" else "nested loops and sums"
            raise CalError(f"{kind} of {total:,} iterations in all: more than {MAX_UNROLL:,}",
                           loc)
        outer, self.loop_product = self.loop_product, max(total, 1)
        try:
            out = []
            for k in range(lo, hi + 1):
                inner = Scope(scope)
                inner.define(var, Fraction(k))
                out.append(body(inner))
            return out
        finally:
            self.loop_product = outer

    def _sum_over(self, e: ast.SumOver, scope: Scope) -> Value:
        """`sum(k in a..b) body`: the bodies' values added left to right (0 for an empty
        range; vectors of one length element by element), exactly while they are numbers."""
        terms = self.unrolled(e.var, e.range, scope, e.loc, "sum",
                              lambda inner: self.value(e.body, inner))
        if not terms:
            return Fraction(0)
        total = terms[0]
        for term in terms[1:]:
            added = [self.arith("+", a, b, e.loc) for a, b in pairs(total, term, "add", e.loc)]
            total = tuple(added) if isinstance(total, tuple) else added[0]
        return total
