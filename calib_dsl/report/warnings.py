"""Warnings instead of silence: a solve that "contracted" but learned little says so."""

from __future__ import annotations

from calib_dsl.ir.program import Program
from calib_dsl.report.rows import narrowed, parameter_rows
from calib_dsl.strategy.solution import Solution


def solve_warnings(prog: Program, res: Solution) -> list[str]:
    """What a user must not miss about a consistent result: no parameter narrowed, or some
    kept their whole search domain (the data did not narrow them)."""
    if res.status == "infeasible":
        return []
    unknowns = [r["name"] for r in parameter_rows(prog, res) if r["kind"] in ("param", "var")]
    if not unknowns:
        return []
    moved = set(narrowed(prog, res))
    if not moved:
        return [f"no parameter was narrowed: the result (guaranteed) says nothing the search "
                f"domains did not ({len(unknowns)} unknowns)"]
    kept = [n for n in unknowns if n not in moved]
    if kept:
        shown = ", ".join(kept[:12]) + (f", ... ({len(kept) - 12} more)" if len(kept) > 12 else "")
        return [f"{len(kept)} of {len(unknowns)} parameters kept their whole search domain "
                f"(the data did not narrow them): {shown}"]
    return []
