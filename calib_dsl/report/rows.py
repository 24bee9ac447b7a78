"""The rows of a report: each declared unknown's domain, result and true value."""

from __future__ import annotations

import math
from typing import Any

from calib_dsl.ir.program import Program
from calib_dsl.ir.status import UNKNOWNS, Status
from calib_dsl.strategy.solution import Solution


def parameter_rows(prog: Program, res: Solution) -> list[dict[str, Any]]:
    s = prog.slots
    rows = []
    variables = {v: i for i, v in enumerate(s.declared_names)}
    for name, i in variables.items():
        slot = s.declared[i]
        rows.append({
            "name": name,
            "kind": s.kinds[slot],
            "domain": prog.domains[name] if prog.domains and name in prog.domains
            else (float(s.lo[slot]), float(s.hi[slot])),
            "result": None if res.status == Status.INFEASIBLE
            else (float(res.lo[slot]), float(res.hi[slot])),
            # a truth the model states; else the centre of a `c +- w` domain, a nominal value
            "true": prog.true_values.get(name) if name in prog.true_stated else None,
            "centre": None if name in prog.true_stated else prog.true_values.get(name),
        })
    return rows


def narrowed(prog: Program, res: Solution) -> list[str]:
    """The declared unknowns whose result is narrower than their search domain."""
    if res.status == Status.INFEASIBLE:
        return []
    out = []
    for r in parameter_rows(prog, res):
        (dlo, dhi), (lo, hi) = r["domain"], r["result"]
        if r["kind"] in UNKNOWNS and (lo > dlo or hi < dhi):
            out.append(r["name"])
    return out


def contraction(domain: tuple[float, float], result: tuple[float, float]) -> float:
    """The result's width over its search domain's (nan when the domain is not finite and
    wider than a point): 1 means the data taught nothing about the unknown."""
    w, wd = result[1] - result[0], domain[1] - domain[0]
    return w / wd if wd > 0 and math.isfinite(wd) else float("nan")
