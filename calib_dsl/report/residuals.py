"""The solve JSON's `residuals` (`solve --residuals`, `--plot`): per data row, the range of
measured minus predicted of each measured column over the result box, with its error bound."""

from __future__ import annotations

import math
from typing import Any

from calib_dsl.analysis.residuals import Ranges
from calib_dsl.ir.model import Model


def residuals_json(model: Model, ranges: Ranges, left_out: dict[str, set[int]]
                   ) -> dict[str, Any]:
    """`rows`: per data row its table, row number (1: the first after the header), line in
    the file, whether the solve used it (`--exclude` left it out), per measured column
    `residual` [lo, hi] and `bound` e, and whether it is an `outlier` (some column's range
    wholly outside [-e, e]: no parameter vector of the box fits it); `outliers`, those rows."""
    tables = {t.name: t for t in model.tables}
    outside = ranges.outside()
    rows: dict[tuple[str, int], dict[str, Any]] = {}
    for i, (table, k, column) in enumerate(zip(ranges.tables, ranges.rows, ranges.columns,
                                               strict=True)):
        t = tables[table]
        number = t.numbers[k - 1] if t.numbers else k
        row = rows.setdefault((table, k), {
            "table": table, "row": number, "line": t.lines[k - 1] if t.lines else None,
            "used": number not in left_out.get(table, set()), "outlier": False,
            "columns": {}})
        row["columns"][column] = {"residual": [_num(ranges.lo[i]), _num(ranges.hi[i])],
                                  "bound": float(ranges.bound[i])}
        row["outlier"] = row["outlier"] or bool(outside[i])
    ordered = sorted(rows.values(), key=lambda r: (r["table"], r["row"]))
    for r in ordered:  # the columns in the table's order
        order = [c.name for c in tables[r["table"]].columns]
        r["columns"] = dict(sorted(r["columns"].items(), key=lambda kv: order.index(kv[0])))
    return {"rows": ordered,
            "outliers": [{"table": r["table"], "row": r["row"], "line": r["line"]}
                         for r in ordered if r["outlier"]]}


def _num(x: float) -> float | str:
    """JSON has no infinity: "-oo" and "+oo", as in the rest of the solve JSON."""
    x = float(x)
    return ("+oo" if x > 0 else "-oo") if math.isinf(x) else x


def render_residuals(found: dict[str, Any]) -> str:
    rows = found["rows"]
    left = sum(not r["used"] for r in rows)
    head = (f"residuals: {len(rows)} rows ({left} left out by --exclude), "
            f"{len(found['outliers'])} outliers of the result (a measured value minus every "
            "prediction over the box lies outside its error bound)")
    lines = [head] + [f"  outlier: {r['table']} row {r['row']} (line {r['line']})"
                      for r in found["outliers"][:20]]
    if len(found["outliers"]) > 20:
        lines.append(f"  ... and {len(found['outliers']) - 20} more")
    return "\n".join(lines)
