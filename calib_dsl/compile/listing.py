"""The primitive-constraint listing a user reads: counts, variables, one primitive a line."""

from __future__ import annotations

import json
from pathlib import Path

from calib_dsl.ir.primitives import Primitive, format_const
from calib_dsl.ir.program import Program

INFIX = {"add": "+", "sub": "-", "mul": "*", "div": "/"}


def render_primitive(p: Primitive, names: list[str]) -> str:
    a = [names[s] for s in p.args]
    o = [names[s] for s in p.out]
    if p.op in INFIX:
        rhs = f"{a[0]} {INFIX[p.op]} {a[1]}"
    elif p.op == "neg":
        rhs = f"-{a[0]}"
    elif p.op == "pow":
        rhs = f"{a[0]}^{int(p.param or 0)}"
    elif p.op == "rot":
        return f"({o[0]}, {o[1]}) = rot({a[0]}, ({a[1]}, {a[2]}))"
    else:
        rhs = f"{p.op}({', '.join(a)})"
    return f"{o[0]} = {rhs}"


def render_listing(prog: Program) -> str:
    c = prog.counts()
    s = prog.slots
    ops = ", ".join(f"{k} {v}" for k, v in c["ops"].items())
    lines = [
        f"# calibc listing of {prog.source} (formulation: {prog.formulation})",
        f"# {c['variables']} variables ({c['declared']} declared, {c['temporaries']} temporaries),"
        f" {c['constants']} constants",
        f"# {c['primitives']} primitives in {c['groups']} groups over {c['levels']} levels: {ops}",
        "",
        "variables:",
    ]
    width = max((len(n) for n, k in zip(s.names, s.kinds, strict=True) if k != "const"),
                default=1)
    for i, (name, kind) in enumerate(zip(s.names, s.kinds, strict=True)):
        capped = kind == "temp" and (s.lo[i] > -float("inf") or s.hi[i] < float("inf"))
        if (kind != "const" and kind != "temp") or capped:
            dom = format_const(s.lo[i], s.hi[i]) if s.lo[i] == s.hi[i] else \
                f"[{_b(s.lo[i])}, {_b(s.hi[i])}]"
            lines.append(f"  {name:<{width}}  in {dom}  ({kind})")
    temps = sum(1 for k in s.kinds if k == "temp")
    if temps:
        lines.append(f"  ({temps} temporaries t1..t{temps}, each in ]-oo, +oo["
                     " unless constrained)")
    lines += ["", "primitives:"]
    texts = [render_primitive(p, s.names) for p in prog.primitives]
    pad = min(max((len(t) for t in texts), default=0), 60)
    for p, text in zip(prog.primitives, texts, strict=True):
        where = f"  # {Path(p.loc.file).name}:{p.loc.line}" if p.loc else ""
        lines.append(f"  {text:<{pad}}{where}")
    return "\n".join(lines) + "\n"


def listing_json(prog: Program) -> str:
    return json.dumps(prog.counts(), indent=2)


def _b(x: float) -> str:
    return format_const(x, x)
