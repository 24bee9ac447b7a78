"""What `calibc solve` prints: a table of the declared unknowns, and a summary."""

from __future__ import annotations

import math
from typing import Any

from calib_dsl.analysis.identify import render
from calib_dsl.ir.program import Program
from calib_dsl.report.extras import Extras
from calib_dsl.report.rows import narrowed, parameter_rows
from calib_dsl.strategy.solution import Solution


def render_table(prog: Program, res: Solution, extra: Extras | None = None) -> str:
    extra = extra or Extras()
    rows = parameter_rows(prog, res)
    lsq = extra.estimate is not None
    head = f"{'name':<10} {'search domain':<26} {'result':<36} {'width':>9} {'ratio':>9}"
    head += f" {'least squares':>14}" if lsq else ""
    lines = [head, "-" * len(head)]
    unident = extra.not_identifiable()
    for r in rows:
        dom = _iv(r["domain"])
        if r["result"] is None:
            lines.append(f"{r['name']:<10} {dom:<26} {'(empty)':<36}")
            continue
        lo, hi = r["result"]
        w = hi - lo
        wd = r["domain"][1] - r["domain"][0]
        ratio = w / wd if wd > 0 and math.isfinite(wd) else float("nan")
        est = extra.lsq_value(r["name"])
        col = f" {est:>14.9g}" if est is not None else ""
        mark = _truth_mark(r) + ("  (not identifiable alone)" if r["name"] in unident else "")
        lines.append(f"{r['name']:<10} {dom:<26} {_iv(r['result'], 10):<36} {w:>9.3g} "
                     f"{ratio:>9.3g}{col}{mark}")
    return "\n".join(lines)


_NOTHING = ("note: no parameter was narrowed. The result is still guaranteed (no solution "
            "lost), but it says\nnothing the search domains did not: from domains this wide "
            "the model is too far from linear\nfor propagation and for the linear relaxation "
            "(docs/tutorial.md, section 4). Narrower domains,\ne.g. around a first "
            "calibration, do contract.")


def render_summary(prog: Program, res: Solution, strategy: str,
                   extra: Extras | None = None) -> str:
    extra = extra or Extras()
    c = prog.counts()
    lines = [f"status: {res.status}", f"stopped: {res.stop}", f"sweeps: {res.sweeps}"
             + (f", LP rounds: {res.lp_rounds} (and {res.reused_rounds} reusing their multipliers)"
                if strategy == "tight" else ""),
             f"primitives: {c['primitives']} ({c['variables']} variables)",
             f"strategy: {strategy}, formulation: {prog.formulation}",
             f"time: {res.seconds:.3f} s"]
    if res.split:
        lines.append(f"split: {' '.join(res.split)} (not identifiable alone) cut into pieces; "
                     f"the result is the hull of the {len(res.pieces)} that hold solutions")
    if prog.centred:
        lines.append("prior: the domains of " + " ".join(prog.centred) + " are centred on the "
                     "least-squares estimate of these data (lsq +- "
                     + "/".join(sorted({f"{w:g}" for _, w in prog.centred.values()}))
                     + "): the results hold within that prior")
    unknowns = [i for i in prog.slots.declared if prog.slots.kinds[i] in ("param", "var")]
    if res.status != "infeasible" and unknowns and not narrowed(prog, res):
        lines += ["", _NOTHING]
    if res.emptied is not None:
        e = res.emptied
        where = f"{e.loc}: " if e.loc else ""
        prim = f" (primitive {e.primitive})" if e.primitive else ""
        lines.append(f"{where}the data and the model are inconsistent: the domain of "
                     f"{e.variable} became empty{prim}")
    if extra.skipped:
        lines += ["", extra.skipped]
    if extra.info is not None:
        lines += ["", render(extra.info)]
        for text, lo, hi in extra.combinations:
            lines.append(f"guaranteed: {text} in [{lo:.10g}, {hi:.10g}]")
    if extra.estimate is not None:
        e = extra.estimate
        inside = [n for n, r in ((n, _result_of(prog, res, n)) for n in e.names)
                  if r is not None and not r[0] <= (extra.lsq_value(n) or 0.0) <= r[1]]
        lines += ["", f"least squares: {'converged' if e.converged else 'NOT converged'}, "
                  f"residuals rms {e.rms:.3g} and max {e.worst:.3g} (in error bounds)",
                  "least-squares estimate inside the guaranteed enclosure: "
                  + ("yes" if not inside else "NO for " + " ".join(inside))]
    return "\n".join(lines)


def _result_of(prog: Program, res: Solution, name: str) -> tuple[float, float] | None:
    s = prog.slots
    if name not in s.declared_names:
        return None
    slot = s.declared[s.declared_names.index(name)]
    return float(res.lo[slot]), float(res.hi[slot])


def _truth_mark(r: dict[str, Any]) -> str:
    t = r["true"]
    if t is None or r["result"] is None:
        return ""
    lo, hi = r["result"]
    return "  true inside" if lo <= t <= hi else "  TRUE VALUE OUTSIDE"


def _iv(b: tuple[float, float], digits: int = 6) -> str:
    return f"[{_f(b[0], digits)}, {_f(b[1], digits)}]"


def _f(x: float, digits: int) -> str:
    if math.isinf(x):
        return "+oo" if x > 0 else "-oo"
    return f"{x:.{digits}g}"
