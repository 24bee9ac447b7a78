"""Warnings instead of silence: a solve that "contracted" but learned little says so (what
they name is computed by the pipeline: sections.py's `leverage`)."""

from __future__ import annotations

from calib_dsl.analysis.leverage import Leverage
from calib_dsl.ir.program import Program
from calib_dsl.ir.status import UNKNOWNS, Status
from calib_dsl.outliers.rows import Row
from calib_dsl.report.extras import Extras
from calib_dsl.report.rows import narrowed, parameter_rows
from calib_dsl.strategy.solution import Solution


def solve_warnings(prog: Program, res: Solution, extra: Extras | None = None) -> list[str]:
    """What a user must not miss about a consistent result: no parameter narrowed, or some
    kept their whole search domain (the data did not narrow them), or a parameter that one
    data row carries (`extra.heavy`, sections.py's `leverage`: its rows named)."""
    if res.status == Status.INFEASIBLE:
        return []
    return _domains(prog, res) + (_leverage(extra.heavy) if extra is not None else [])


def _leverage(heavy: list[tuple[Leverage, Row]]) -> list[str]:
    """A parameter whose estimate one data row carries: a fault there would move the result,
    not show as an inconsistency."""
    if not heavy:
        return []
    parts = [f"{h.parameter} {h.share:.0%} on {r.file}:{r.line} (data row {r.row})"
             for h, r in heavy[:6]]
    more = f", ... ({len(heavy) - 6} more)" if len(heavy) > 6 else ""
    return [f"one data row carries most of what the data say about {len(heavy)} "
            f"parameter{'s' if len(heavy) > 1 else ''} (a fault there would move the result, "
            f"not show as an inconsistency): {'; '.join(parts)}{more}"]


def _domains(prog: Program, res: Solution) -> list[str]:
    unknowns = [r["name"] for r in parameter_rows(prog, res) if r["kind"] in UNKNOWNS]
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
