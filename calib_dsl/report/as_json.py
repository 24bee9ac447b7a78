"""What `calibc solve --json` writes: the same result as plain JSON data."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from calib_dsl.analysis.identify import identifiability_json
from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.ir.program import Program
from calib_dsl.ir.status import UNKNOWNS, Status
from calib_dsl.report.accuracy import accuracy_json
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
            "unit": prog.units.get(r["name"]),
        }
        if r["name"] in prog.centred:  # the domain is the data's least-squares estimate +- w
            centre, w = prog.centred[r["name"]]
            params[r["name"]]["prior"] = {"lsq": centre, "half_width": w}
        if extra.info is not None:
            params[r["name"]]["identifiable"] = r["name"] not in unident
        if extra.estimate is not None:
            params[r["name"]]["least_squares"] = extra.lsq_value(r["name"])
        if extra.inner is not None and res.status != Status.INFEASIBLE:
            inner = extra.inner_of(r["name"]) if r["kind"] in UNKNOWNS else None
            params[r["name"]]["inner"] = None if inner is None else list(inner)
            params[r["name"]]["certified"] = extra.certified_of(r["name"]) \
                if r["kind"] in UNKNOWNS else None
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
    if extra.shaved is not None:
        out["shaved"] = {"parameters": list(extra.shaved.names),
                         "seconds": extra.shaved.seconds,
                         "lp_rounds": extra.shaved.work.lp_rounds,
                         "sweeps": extra.shaved.work.sweeps,
                         "halved": list(extra.shaved.halved)}
    if extra.estimate is not None:
        e = extra.estimate
        out["least_squares"] = {"converged": e.converged, "rms": e.rms, "max": e.worst}
    if extra.accuracy is not None:
        out["accuracy"] = accuracy_json(extra.accuracy, extra.length_unit)
    if res.history is not None:
        out["history"] = history_json(prog, res)
    if res.emptied is not None:
        e = res.emptied
        out["emptied"] = {"variable": e.variable, "location": str(e.loc) if e.loc else None,
                          "primitive": e.primitive}
    return out


def history_json(prog: Program, res: Solution) -> dict[str, Any]:
    """The width of each declared unknown after each step of the solve (`calibc plot --kind
    history`): the unknowns' names, then per step its label, seconds and widths."""
    assert res.history is not None
    return {"parameters": list(prog.slots.declared_names),
            "steps": [{"step": s.label, "seconds": s.seconds,
                       "widths": [_num(float(w)) for w in s.widths]}
                      for s in res.history.steps]}


def read_result(path: str | Path) -> dict[str, Any]:
    """A result JSON (`solve --json`, `validate --json`), or a user error that says why not."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as err:
        raise CalError(f"cannot read '{path}': {err.strerror or err}") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        raise CalError(f"'{path}' is not a result JSON: {err}") from None
    if not isinstance(data, dict):
        raise CalError(f"'{path}' is not a result JSON (calibc solve or validate --json "
                       "writes one)")
    check_intervals(path, data)
    return data


def check_intervals(path: str | Path, data: dict[str, Any]) -> None:
    """Each parameter's domain and result as a solve writes them: two numbers (or -oo, +oo),
    lo <= hi, or no result (an infeasible solve's). A damaged or hand-edited file would
    otherwise be drawn, reported or exported as a guaranteed enclosure."""
    params = data.get("parameters")
    if params is None:  # (a validation's JSON has none)
        return
    if not isinstance(params, dict):
        raise CalError(f"'{path}' is malformed: its 'parameters' is not an object; write it "
                       "anew (calibc solve --json)")
    for name, p in params.items():
        for key in ("domain", "result"):
            v = p.get(key) if isinstance(p, dict) else ()
            if v is None:
                continue
            if not _interval(v):
                raise CalError(f"'{path}' is malformed: the {key} of '{name}', {v!r}, is not "
                               "an interval (lo <= hi); write it anew (calibc solve --json)")


def _interval(v: Any) -> bool:
    try:
        lo, hi = (math.inf if x == "+oo" else -math.inf if x == "-oo" else float(x) for x in v)
    except (TypeError, ValueError):
        return False
    return bool(lo <= hi)  # (False for a NaN end)


def _num(x: float) -> float | str:
    """JSON has no infinity: infinite bounds are written as the strings "-oo" and "+oo"."""
    if math.isinf(x):
        return "+oo" if x > 0 else "-oo"
    return x
