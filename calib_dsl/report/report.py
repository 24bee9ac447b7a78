"""What `calibc solve` tells: a table of the declared unknowns, and the same as JSON."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from calib_dsl.ir.program import Program
from calib_dsl.strategy.solution import Solution


class Extras:
    """Optional sections of the report: identifiability, and a least-squares estimate."""

    def __init__(self) -> None:
        self.info: Any = None  # identify.Identifiability
        self.combinations: list[tuple[str, float, float]] = []
        self.estimate: Any = None  # lsq.Estimate
        self.seconds = 0.0
        self.skipped = ""

    def identify(self, prog: Program, res: Solution, use_lp: bool) -> None:
        import time

        from calib_dsl.analysis.identify import (
            ROUTINE_MAX_PRIMITIVES,
            analyse,
            combination_enclosures,
        )
        from calib_dsl.frontend.diagnostics import CalError

        start = time.perf_counter()
        if len(prog.primitives) > ROUTINE_MAX_PRIMITIVES:
            self.skipped = (f"identifiability: not analysed in solve for a program of "
                            f"{len(prog.primitives)} primitives (run `calibc identify`)")
            return
        try:
            self.info = analyse(prog)
        except CalError:  # no nominal values to linearize at: say nothing rather than guess
            return
        self.combinations = combination_enclosures(prog, self.info, res.lo, res.hi, use_lp,
                                                   pieces=res.pieces, known=res.combinations)
        self.seconds += time.perf_counter() - start

    def least_squares(self, prog: Program, res: Solution) -> None:
        import time

        from calib_dsl.analysis.lsq import estimate
        from calib_dsl.relax.linearize import independents

        start = time.perf_counter()
        ind = independents(prog)
        mid = 0.5 * (res.lo[ind] + res.hi[ind])
        self.estimate = estimate(prog, start=mid if all(map(math.isfinite, mid)) else None)
        self.seconds += time.perf_counter() - start

    def not_identifiable(self) -> set[str]:
        if self.info is None:
            return set()
        return {n for members, _ in self.info.groups for n in members}

    def lsq_value(self, name: str) -> float | None:
        if self.estimate is None or name not in self.estimate.names:
            return None
        return float(self.estimate.values[self.estimate.names.index(name)])


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
            "result": None if res.status == "infeasible"
            else (float(res.lo[slot]), float(res.hi[slot])),
            "true": prog.true_values.get(name),
        })
    return rows


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


def narrowed(prog: Program, res: Solution) -> list[str]:
    """The declared unknowns whose result is narrower than their search domain."""
    if res.status == "infeasible":
        return []
    out = []
    for r in parameter_rows(prog, res):
        (dlo, dhi), (lo, hi) = r["domain"], r["result"]
        if r["kind"] in ("param", "var") and (lo > dlo or hi < dhi):
            out.append(r["name"])
    return out


_NOTHING = ("note: no parameter was narrowed. The result is still guaranteed (no solution "
            "lost), but it says\nnothing the search domains did not: from domains this wide "
            "the model is too far from linear\nfor propagation and for the linear relaxation "
            "(docs/tutorial.md, section 6). Narrower domains,\ne.g. around a first "
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
        from calib_dsl.analysis.identify import render

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
        if extra.info is not None:
            params[r["name"]]["identifiable"] = r["name"] not in unident
        if extra.estimate is not None:
            params[r["name"]]["least_squares"] = extra.lsq_value(r["name"])
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
        from calib_dsl.analysis.identify import identifiability_json

        out["identifiability"] = identifiability_json(extra.info)
        out["identifiability"]["combinations"] = [
            {"combination": t, "result": [_num(lo), _num(hi)]} for t, lo, hi in extra.combinations]
    if extra.estimate is not None:
        e = extra.estimate
        out["least_squares"] = {"converged": e.converged, "rms": e.rms, "max": e.worst}
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
