"""What `calibc solve` tells: a table of the declared unknowns, and the same as JSON."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from .program import Program
from .propagate import Result


def parameter_rows(prog: Program, res: Result) -> list[dict[str, Any]]:
    s = prog.slots
    rows = []
    variables = {v: i for i, v in enumerate(s.declared_names)}
    for name, i in variables.items():
        slot = s.declared[i]
        rows.append({
            "name": name,
            "kind": s.kinds[slot],
            "domain": (float(s.lo[slot]), float(s.hi[slot])),
            "result": None if res.status == "infeasible"
            else (float(res.lo[slot]), float(res.hi[slot])),
            "true": prog.true_values.get(name),
        })
    return rows


def render_table(prog: Program, res: Result) -> str:
    rows = parameter_rows(prog, res)
    head = f"{'name':<10} {'search domain':<26} {'result':<36} {'width':>9} {'ratio':>9}"
    lines = [head, "-" * len(head)]
    for r in rows:
        dom = _iv(r["domain"])
        if r["result"] is None:
            lines.append(f"{r['name']:<10} {dom:<26} {'(empty)':<36}")
            continue
        lo, hi = r["result"]
        w = hi - lo
        wd = r["domain"][1] - r["domain"][0]
        ratio = w / wd if wd > 0 and math.isfinite(wd) else float("nan")
        mark = _truth_mark(r)
        lines.append(f"{r['name']:<10} {dom:<26} {_iv(r['result'], 10):<36} {w:>9.3g} "
                     f"{ratio:>9.3g}{mark}")
    return "\n".join(lines)


def render_summary(prog: Program, res: Result, strategy: str) -> str:
    c = prog.counts()
    lines = [f"status: {res.status}", f"stopped: {res.stop}", f"sweeps: {res.sweeps}"
             + (f", LP rounds: {res.rounds}" if strategy == "tight" else ""),
             f"primitives: {c['primitives']} ({c['variables']} variables)",
             f"strategy: {strategy}, formulation: {prog.formulation}",
             f"time: {res.seconds:.3f} s"]
    if res.emptied is not None:
        e = res.emptied
        where = f"{e.loc}: " if e.loc else ""
        prim = f" (primitive {e.primitive})" if e.primitive else ""
        lines.append(f"{where}the data and the model are inconsistent: the domain of "
                     f"{e.variable} became empty{prim}")
    return "\n".join(lines)


def result_json(prog: Program, res: Result, strategy: str) -> dict[str, Any]:
    params = {}
    for r in parameter_rows(prog, res):
        params[r["name"]] = {
            "kind": r["kind"],
            "domain": [_num(x) for x in r["domain"]],
            "result": None if r["result"] is None else [_num(x) for x in r["result"]],
            "true": r["true"],
        }
    out: dict[str, Any] = {
        "model": str(Path(prog.source)),
        "status": res.status,
        "stop": res.stop,
        "sweeps": res.sweeps,
        "lp_rounds": res.rounds,
        "seconds": res.seconds,
        "primitives": len(prog.primitives),
        "formulation": prog.formulation,
        "strategy": strategy,
        "parameters": params,
    }
    if res.emptied is not None:
        e = res.emptied
        out["emptied"] = {"variable": e.variable, "location": str(e.loc) if e.loc else None,
                          "primitive": e.primitive}
    return out


def _truth_mark(r: dict[str, Any]) -> str:
    t = r["true"]
    if t is None or r["result"] is None:
        return ""
    lo, hi = r["result"]
    return "  true inside" if lo <= t <= hi else "  TRUE VALUE OUTSIDE"


def _num(x: float) -> float | str:
    """JSON has no infinity: infinite bounds are written as the strings "-oo" and "+oo"."""
    if math.isinf(x):
        return "+oo" if x > 0 else "-oo"
    return x


def _iv(b: tuple[float, float], digits: int = 6) -> str:
    return f"[{_f(b[0], digits)}, {_f(b[1], digits)}]"


def _f(x: float, digits: int) -> str:
    if math.isinf(x):
        return "+oo" if x > 0 else "-oo"
    return f"{x:.{digits}g}"
