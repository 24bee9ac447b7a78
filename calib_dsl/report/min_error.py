"""What `solve` says about the error bound and bad rows: the smallest consistent bound
(`--min-error NAME`) and, for inconsistent data, the rows at fault; text and JSON."""

from __future__ import annotations

from typing import Any

from calib_dsl.analysis.min_error import MinError
from calib_dsl.ir.status import Status
from calib_dsl.outliers.conflict import Conflict


def render_min_error(r: MinError) -> str:
    lo = "-" if r.lo is None else f"{r.lo:.6g}"
    lines = [f"smallest consistent error bound for {r.name}: in [{lo}, {r.hi:.6g}]"
             + ("" if r.lo is None else f" ({100 * (r.hi / r.lo - 1):.1f} % wide)")]
    lines.append(f"  upper end {r.hi:.6g}: proven feasible: at the point below every row holds "
                 "under interval evaluation")
    if r.lo is None:
        lines.append("  lower end: no tried value was proven infeasible (the data may be "
                     "consistent with much smaller bounds)")
    else:
        lines.append(f"  lower end {r.lo:.6g}: proven infeasible by the solve (or its proof "
                     "effort: fine rounds, a split)")
    tried = ", ".join(f"{v:.6g} {'infeasible' if s == Status.INFEASIBLE else 'not refuted'}"
                      for v, s in r.trials)
    lines.append(f"  values tried: {tried or 'none'}")
    lines.append(f"rows that bind at the upper end (residual within {r.within:.0%} of it): "
                 f"{len(r.binding)}")
    for b in r.binding:
        lines.append(f"  {b.file}:{b.line} (data row {b.row}): residual {b.residual:.6g}")
    shown = " ".join(f"{n}={v:.9g}" for n, v in r.point.items())
    lines.append(f"point: {shown}")
    return "\n".join(lines)


def min_error_json(r: MinError) -> dict[str, Any]:
    return {"name": r.name, "bracket": [r.lo, r.hi],
            "binding": [{"file": b.file, "line": b.line, "row": b.row, "residual": b.residual}
                        for b in r.binding],
            "point": r.point,
            "trials": [{"value": v, "status": s} for v, s in r.trials]}


def render_conflict(c: Conflict) -> str:
    if c.priors:
        return "\n".join(["the priors at fault: with these search domains widened the data are "
                          "proven consistent (a point satisfies every row under interval "
                          "evaluation), so no row need be wrong:"]
                         + [f"  {f.text()}" for f in c.priors]
                         + ["widen them, or check their nominal values, before leaving out "
                            "any row"])
    units = ["units to check (every row looks wrong; no row is named):"] \
        + [f"  {u}" for u in c.units] if c.units else []
    rows = ", ".join(f"{r.file}:{r.line} (data row {r.row}, {r.residual:.3g} bounds off by "
                     "least squares)" for r in c.rows)
    if not c.rows:
        return "\n".join(units)
    if not c.consistent:
        return "\n".join(units + [
            f"the worst rows by least squares: {rows}; without them the rest was not "
            "proven consistent (more rows may be at fault, or the model does not fit; "
            "or its rows compare computed values with no error bound of their own, as "
            "a circle's points with one radius, which a fitted point cannot be proven "
            "to satisfy exactly: solve again with --exclude and the first of them)"])
    one = len(c.rows) == 1
    lines = units + [
        f"without {'this row' if one else 'these rows'} the rest of the data is proven "
        f"consistent (a point satisfies every other row under interval evaluation): {rows}",
        "every conflicting set of rows contains " + ("it" if one else "one of them")]
    if c.needed is not None:
        lines.append("each of them is needed (with any one back the rest was not proven "
                     "consistent)" if c.needed else "not proven minimal: fewer of them may do")
    return "\n".join(lines)


def conflict_json(c: Conflict) -> dict[str, Any]:
    return {"rows": [{"file": r.file, "line": r.line, "row": r.row, "residual": r.residual}
                     for r in c.rows],
            "rest_consistent": c.consistent, "each_needed": c.needed, "units": c.units,
            "priors": [{"name": f.name, "wanted": f.wanted, "end": f.end,
                        "domain": [f.lo, f.hi]} for f in c.priors]}
