"""What `calibc solve --json` writes: the same result as plain JSON data."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from calib_dsl.analysis.identify import identifiability_json
from calib_dsl.ir.program import Program
from calib_dsl.report.extras import Extras
from calib_dsl.report.rows import narrowed, parameter_rows
from calib_dsl.report.tightness import tightness
from calib_dsl.strategy.solution import Solution


def result_json(prog: Program, res: Solution, strategy: str,
                extra: Extras | None = None) -> dict[str, Any]:
    extra = extra or Extras()
    params = {}
    unident = extra.not_identifiable()
    for r in parameter_rows(prog, res):
        params[r["name"]] = {
            "kind": r["kind"],
            "domain": [_num(x) for x in r["domain"]],
            "result": None if r["result"] is None else [_num(x) for x in r["result"]],
            "true": r["true"],
        }
        if r["name"] in prog.centred:  # the domain is the data's least-squares estimate +- w
            centre, w = prog.centred[r["name"]]
            params[r["name"]]["prior"] = {"lsq": centre, "half_width": w}
        if extra.info is not None:
            params[r["name"]]["identifiable"] = r["name"] not in unident
        if extra.estimate is not None:
            params[r["name"]]["least_squares"] = extra.lsq_value(r["name"])
        if extra.inner is not None and res.status != "infeasible":
            inner = extra.inner_of(r["name"]) if r["kind"] in ("param", "var") else None
            params[r["name"]]["inner"] = None if inner is None else list(inner)
    out: dict[str, Any] = {
        "model": str(Path(prog.source)),
        "status": res.status,
        "stop": res.stop,
        "sweeps": res.sweeps,
        "lp_rounds": res.lp_rounds,
        "reused_rounds": res.reused_rounds,
        "seconds": res.seconds,
        "primitives": len(prog.primitives),
        "formulation": prog.formulation,
        "strategy": strategy,
        "parameters": params,
        "narrowed": narrowed(prog, res),  # the unknowns the solve made narrower
        "split": {"parameters": list(res.split), "pieces": len(res.pieces)},
    }
    if extra.info is not None:
        out["identifiability"] = identifiability_json(extra.info)
        out["identifiability"]["combinations"] = [
            {"combination": t, "result": [_num(lo), _num(hi)]} for t, lo, hi in extra.combinations]
    t = tightness(prog, res, extra)
    if t is not None:
        out["tightness"] = t
    if extra.estimate is not None:
        e = extra.estimate
        out["least_squares"] = {"converged": e.converged, "rms": e.rms, "max": e.worst}
    if res.emptied is not None:
        e = res.emptied
        out["emptied"] = {"variable": e.variable, "location": str(e.loc) if e.loc else None,
                          "primitive": e.primitive}
    return out


def _num(x: float) -> float | str:
    """JSON has no infinity: infinite bounds are written as the strings "-oo" and "+oo"."""
    if math.isinf(x):
        return "+oo" if x > 0 else "-oo"
    return x
