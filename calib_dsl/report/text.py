"""What `calibc solve` prints: a table of the declared unknowns, and a summary."""

from __future__ import annotations

import math
from decimal import ROUND_CEILING, ROUND_FLOOR, Decimal
from typing import Any

from calib_dsl.analysis.identify import render
from calib_dsl.ir.program import Program
from calib_dsl.ir.status import UNKNOWNS, Consistency, Status
from calib_dsl.report.accuracy import accuracy_json, render_accuracy
from calib_dsl.report.extras import Extras
from calib_dsl.report.rows import contraction, narrowed, parameter_rows
from calib_dsl.report.tightness import render_tightness, tightness, width_ratio
from calib_dsl.report.verdict import UNDECIDED_TABLE
from calib_dsl.strategy.solution import Solution


def render_table(prog: Program, res: Solution, extra: Extras | None = None,
                 every: bool = False, verdict: str | None = None) -> str:
    """One line per declared unknown (by default only those the data narrowed or cannot
    identify alone; `every`: all): search domain, result and certified inner interval as
    printed, each end rounded to DIGITS significant digits away from the inside of the
    interval (inward for the inner one), so what is printed keeps what is proven. With the
    `verdict` undecided, a stated true value inside reads `true in box`: no solution is
    proven to exist."""
    extra = extra or Extras()
    rows = parameter_rows(prog, res)
    kept = [] if every else _kept(rows, extra)
    rows = [r for r in rows if r["name"] not in kept]
    table = [_row(r, extra) for r in rows]
    head = ["name", "search domain", "result", "width", "ratio"]
    head += ["certified inner", "outer/inner"] if extra.inner is not None else []
    head += ["least squares"] if extra.estimate is not None else []
    widths = [max([len(h)] + [len(t[i]) for t in table if i < len(t)])
              for i, h in enumerate(head)]
    right = {"width", "ratio", "outer/inner", "least squares"}

    def line(cells: list[str]) -> str:
        return " ".join(c.rjust(w) if h in right else c.ljust(w)
                        for c, w, h in zip(cells, widths, head, strict=False)).rstrip()

    centres = any(r["true"] is None and r.get("centre") is not None for r in rows)
    out = [_legend(extra, centres), line(head), "-" * len(line(head))]
    if verdict == Consistency.UNDECIDED:
        out.insert(1, UNDECIDED_TABLE)
    for r, cells in zip(rows, table, strict=True):
        out.append(line(cells) + _marks(r, extra, verdict == Consistency.UNDECIDED))
    if kept:
        shown = " ".join(kept[:12]) + (f" ... ({len(kept) - 12} more)" if len(kept) > 12 else "")
        out.append(f"({len(kept)} more kept their whole search domain, not shown: {shown}; "
                   "--all lists them)")
    return "\n".join(out)


def _legend(extra: Extras, centres: bool = False) -> str:
    """What the columns mean, above them (docs/tutorial.md, section 5)."""
    lines = ["# result: proven to hold every consistent value (rounded outward); "
             "ratio: its width / the domain's"]
    if extra.inner is not None:
        lines.append("# certified inner: values proven to be taken (rounded inward); "
                     "outer/inner: 1 = the best possible enclosure")
    if centres:
        lines.append("# centre: c of a `c +- w` domain, a nominal value the data may exclude; "
                     "`true v` in the model marks a true value instead")
    return "\n".join(lines)


def _kept(rows: list[dict[str, Any]], extra: Extras) -> list[str]:
    """The unknowns whose result is their whole search domain and that the data could
    identify alone: known beforehand as well as the data know them."""
    unident = extra.not_identifiable()
    return [r["name"] for r in rows
            if r["kind"] in UNKNOWNS and r["result"] is not None
            and tuple(r["result"]) == tuple(r["domain"]) and r["name"] not in unident]


def _row(r: dict[str, Any], extra: Extras) -> list[str]:
    dlo, dhi = r["domain"]
    dom = f"[{_nearest(dlo)}, {_nearest(dhi)}]"
    if r["result"] is None:
        return [r["name"], dom, "(empty)"]
    lo, hi = r["result"]
    w = hi - lo
    ratio = contraction(r["domain"], r["result"])
    # an end the solve left at the domain's prints as the domain does (the declared value;
    # its float is already the declared number rounded outward)
    result = (f"[{_nearest(lo) if lo == dlo else _f(lo, ROUND_FLOOR)}, "
              f"{_nearest(hi) if hi == dhi else _f(hi, ROUND_CEILING)}]")
    cells = [r["name"], dom, result, f"{w:.3g}", f"{ratio:.3g}"]
    if extra.inner is not None:
        inner = extra.inner_of(r["name"]) if r["kind"] in UNKNOWNS else None
        q = width_ratio(r["result"], inner)
        cells += ["-" if inner is None else printed_interval(inner, inward=True),
                  "-" if q is None else f"{q:.4g}"]
    if extra.estimate is not None:
        est = extra.lsq_value(r["name"])
        cells.append("" if est is None else f"{est:.9g}")
    return cells


def _marks(r: dict[str, Any], extra: Extras, undecided: bool = False) -> str:
    if r["result"] is None:
        return ""
    unident = "  (not identifiable alone)" if r["name"] in extra.not_identifiable() else ""
    mark = _truth_mark(r)
    if undecided:
        mark = mark.replace("true inside", "true in box")
    return mark + unident


_NOTHING = ("note: no parameter was narrowed. The result is still guaranteed (no solution "
            "lost), but it says\nnothing the search domains did not: from domains this wide "
            "the model is too far from linear\nfor propagation and for the linear relaxation "
            "(docs/tutorial.md, section 4). Narrower domains,\ne.g. around a first "
            "calibration, do contract.")


def _extra_time(extra: Extras) -> str:
    """The inner bounds', the shaving's and the accuracy's own clocks, after the solve's."""
    parts = []
    if extra.inner is not None:
        parts.append(f"{extra.inner.seconds:.2f} s for the inner bounds")
    if extra.shaved is not None:
        parts.append(f"{extra.shaved.seconds:.2f} s shaving")
    if extra.accuracy is not None:
        parts.append(f"{extra.accuracy_seconds:.2f} s for the accuracy")
    return f" (and {', '.join(parts)})" if parts else ""


def render_summary(prog: Program, res: Solution, strategy: str,
                   extra: Extras | None = None) -> str:
    extra = extra or Extras()
    c = prog.counts()
    lines = [f"status: {res.status}", f"stopped: {res.stop}", f"sweeps: {res.sweeps}"
             + (f", LP rounds: {res.lp_rounds} (and {res.reused_rounds} re-certifying the last "
                f"round's solutions on the smaller box)"
                if strategy == "tight" else ""),
             f"primitives: {c['primitives']} ({c['variables']} variables)",
             f"strategy: {strategy}, formulation: {prog.formulation}",
             f"time: {res.seconds:.3f} s" + _extra_time(extra)]
    if extra.shaved is not None:
        lines.append(f"shaved: {' '.join(extra.shaved.names)} (the gap between each end and "
                     "the certified inner bound contracted as a slice of its own)")
        if extra.shaved.halved:
            lines.append(f"halved: {' '.join(extra.shaved.halved)} (left their whole domain "
                         "while the result was still loose: cut in halves, the hull kept)")
    if res.split:
        lines.append(f"split: {' '.join(res.split)} (not identifiable alone) cut into pieces; "
                     f"the result is the hull of the {len(res.pieces)} that hold solutions")
    if prog.centred:
        lines.append("prior: the domains of " + " ".join(prog.centred) + " are centred on the "
                     "least-squares estimate of these data (lsq +- "
                     + "/".join(sorted({f"{w:g}" for _, w in prog.centred.values()}))
                     + "): the results hold within that prior")
    unknowns = [i for i in prog.slots.declared if prog.slots.kinds[i] in UNKNOWNS]
    if res.status != Status.INFEASIBLE and unknowns and not narrowed(prog, res):
        lines += ["", _NOTHING]
    if res.emptied is not None:
        e = res.emptied
        where = f"{e.loc}: " if e.loc else ""
        prim = f" (primitive {e.primitive})" if e.primitive else ""
        lines.append(f"{where}the data and the model are inconsistent: the domain of "
                     f"{e.variable} became empty{prim}")
    t = tightness(prog, res, extra)
    if t is not None:
        lines += ["", *render_tightness(t)]
    if extra.accuracy is not None:
        lines += ["", *render_accuracy(accuracy_json(extra.accuracy, extra.length_unit))]
    if extra.skipped:
        lines += ["", *extra.skipped]
    if extra.info is not None:
        lines += ["", render(extra.info)]
        for text, lo, hi in extra.combinations:
            lines.append(f"guaranteed: {text} in {printed_interval((lo, hi))}")
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
    """A stated true value must lie in the result (outside: a bug); a `c +- w` domain's
    centre is a nominal value, which the data may well exclude (the robot is not nominal)."""
    if r["result"] is None:
        return ""
    lo, hi = r["result"]
    if r["true"] is not None:
        return "  true inside" if lo <= r["true"] <= hi else "  TRUE VALUE OUTSIDE"
    if r.get("centre") is not None:
        return "  centre inside" if lo <= r["centre"] <= hi else "  centre outside"
    return ""


DIGITS = 10  # significant digits of every printed bound


def printed_interval(b: tuple[float, float], inward: bool = False) -> str:
    """[lo, hi] rounded outward (inward: the printed interval inside the true one)."""
    down, up = (ROUND_FLOOR, ROUND_CEILING) if not inward else (ROUND_CEILING, ROUND_FLOOR)
    return f"[{_f(b[0], down)}, {_f(b[1], up)}]"


def _nearest(x: float) -> str:
    """A declared bound: the nearest DIGITS-digit number (what the model says)."""
    if math.isinf(x):
        return "+oo" if x > 0 else "-oo"
    return f"{x:.{DIGITS}g}"


def _f(x: float, rounding: str) -> str:
    if math.isinf(x):
        return "+oo" if x > 0 else "-oo"
    if x == 0:
        return "0"
    d = Decimal(x)  # exact: the float's own value
    q = d.quantize(Decimal(1).scaleb(d.adjusted() - DIGITS + 1), rounding=rounding).normalize()
    e = q.adjusted()
    if -4 <= e < DIGITS:  # as Python prints floats with the g format
        return f"{q:f}"
    mantissa = f"{q.scaleb(-e):f}"
    return f"{mantissa}e{e:+03d}"
