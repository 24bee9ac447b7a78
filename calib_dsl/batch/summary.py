"""The table at the end of a batch: per job, its status, how many unknowns it narrowed, the
median and largest width of their results, its time, and a note (where an inconsistency was
proven, the error, the first warning)."""

from __future__ import annotations

import math
import statistics
from collections import Counter
from typing import Any

from calib_dsl.ir.status import UNKNOWNS, Status

HEAD = ("id", "status", "narrowed", "median width", "max width", "seconds", "note")


def render_summary(lines: list[dict[str, Any]]) -> str:
    rows = [HEAD] + [_row(line) for line in lines]
    widths = [max(len(r[c]) for r in rows) for c in range(len(HEAD) - 1)]
    text = ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=False)) + "  " + r[-1]
            for r in rows]
    counts = Counter(line["status"] for line in lines)
    jobs = f"{len(lines)} job" + ("s" if len(lines) != 1 else "")
    text.append(f"{jobs}: " + ", ".join(f"{n} {s}" for s, n in sorted(counts.items())))
    return "\n".join(t.rstrip() for t in text)


def _row(line: dict[str, Any]) -> tuple[str, ...]:
    result = line.get("result") or {}
    seconds = f"{line.get('seconds', 0.0):.2f}"
    if line["status"] not in (Status.CONTRACTED, Status.INFEASIBLE):
        return (line["id"], line["status"], "-", "-", "-", seconds, _first(line.get("error")))
    if line["status"] == Status.INFEASIBLE:
        e = result.get("emptied") or {}
        where = f" at {e['location']}" if e.get("location") else ""
        note = f"proven inconsistent: {e.get('variable')} emptied{where}"
        return (line["id"], "infeasible", "-", "-", "-", seconds, note)
    widths = unknown_widths(result)
    moved = len(result.get("narrowed", []))
    warnings = result.get("warnings") or []
    return (line["id"], "contracted", f"{moved}/{len(widths)}",
            _num(statistics.median(widths)) if widths else "-",
            _num(max(widths)) if widths else "-", seconds,
            _first(warnings[0]) if warnings else "")


def unknown_widths(result: dict[str, Any]) -> list[float]:
    """The widths of the results of the declared unknowns (params and vars)."""
    out = []
    for p in result.get("parameters", {}).values():
        if p["kind"] in UNKNOWNS and p["result"] is not None:
            lo, hi = (_float(x) for x in p["result"])
            out.append(hi - lo)
    return out


def _float(x: float | str) -> float:
    return {"-oo": -math.inf, "+oo": math.inf}[x] if isinstance(x, str) else float(x)


def _num(x: float) -> str:
    return "oo" if math.isinf(x) else f"{x:.3g}"


def _first(text: str | None) -> str:
    """A note's first line (the last column: its length does not misalign the others)."""
    lines = (text or "").strip().splitlines()
    return lines[0] if lines else ""
