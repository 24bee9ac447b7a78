"""Warnings instead of silence: a solve that "contracted" but learned little says so."""

from __future__ import annotations

from calib_dsl.analysis.leverage import heavy_rows
from calib_dsl.ir.model import Model
from calib_dsl.ir.program import Program
from calib_dsl.outliers.rows import data_rows
from calib_dsl.report.rows import narrowed, parameter_rows
from calib_dsl.settings import Settings
from calib_dsl.strategy.solution import Solution


def solve_warnings(prog: Program, res: Solution, model: Model | None = None,
                   most_primitives: int = Settings.routine_max_primitives) -> list[str]:
    """What a user must not miss about a consistent result: no parameter narrowed, or some
    kept their whole search domain (the data did not narrow them), or a parameter that one
    data row carries (with the model: its rows named)."""
    if res.status == "infeasible":
        return []
    heavy = _leverage(prog, res, model, most_primitives) if model is not None else []
    return _domains(prog, res) + heavy


def _leverage(prog: Program, res: Solution, model: Model, most_primitives: int) -> list[str]:
    """A parameter whose estimate one data row carries: a fault there would move the result,
    not show as an inconsistency."""
    if not model.tables or len(prog.primitives) > most_primitives:
        return []
    heavy = heavy_rows(prog, res.lo, res.hi)
    if not heavy:
        return []
    rows = data_rows(model, prog, [h.data_row for h in heavy])
    parts = [f"{h.parameter} {h.share:.0%} on {r.file}:{r.line} (data row {r.row})"
             for h, r in zip(heavy[:6], rows, strict=False)]
    more = f", ... ({len(heavy) - 6} more)" if len(heavy) > 6 else ""
    return [f"one data row carries most of what the data say about {len(heavy)} "
            f"parameter{'s' if len(heavy) > 1 else ''} (a fault there would move the result, "
            f"not show as an inconsistency): {'; '.join(parts)}{more}"]


def _domains(prog: Program, res: Solution) -> list[str]:
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
