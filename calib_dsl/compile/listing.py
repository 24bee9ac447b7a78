"""The primitive-constraint listing a user reads: counts, variables, one primitive a line."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

from calib_dsl.ir.primitives import Primitive, format_const
from calib_dsl.ir.program import Program
from calib_dsl.ir.rows import Tiled
from calib_dsl.ir.status import SlotKind

INFIX = {"add": "+", "sub": "-", "mul": "*", "div": "/"}


def render_primitive(p: Primitive, names: Sequence[str]) -> str:
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
    every = len(s.lo) if prog.rows is None else prog.rows.shared
    width = max((len(n) for _, n, k in zip(range(every), s.names, s.kinds, strict=False)
                 if k != SlotKind.CONST), default=1)
    shown = len(s.lo) if prog.rows is None else prog.rows.shared
    for i, name, kind in zip(range(shown), s.names, s.kinds, strict=False):
        capped = kind == SlotKind.TEMP and (s.lo[i] > -float("inf") or s.hi[i] < float("inf"))
        if (kind != SlotKind.CONST and kind != SlotKind.TEMP) or capped:
            dom = format_const(s.lo[i], s.hi[i]) if s.lo[i] == s.hi[i] else \
                f"[{_b(s.lo[i])}, {_b(s.hi[i])}]"
            lines.append(f"  {name:<{width}}  in {dom}  ({kind})")
    if prog.rows is not None:
        lines += _row_variables(prog)
    temps = c["temporaries"]
    if temps and prog.rows is not None:
        named = sum(1 for k in s.kinds.shared if k == SlotKind.TEMP) if isinstance(s.kinds, Tiled) \
            else temps
        row = sum(1 for k in s.kinds.template if k == SlotKind.TEMP) if isinstance(s.kinds, Tiled) \
            else 0
        lines.append(f"  ({temps} temporaries: t1..t{named + row}, the loop's t{named + 1}[k]"
                     f"..t{named + row}[k] once per row k; each in ]-oo, +oo[ unless "
                     "constrained)")
    elif temps:
        lines.append(f"  ({temps} temporaries t1..t{temps}, each in ]-oo, +oo["
                     " unless constrained)")
    lines += ["", "primitives:"]
    if prog.rows is None:
        lines += _primitive_lines(prog.primitives, s.names, "  ")
    else:  # a loop compiled once: its body once, for all its rows
        assert isinstance(prog.primitives, Tiled)
        r = prog.rows
        lines += _primitive_lines(prog.primitives.shared, s.names, "  ")
        first, last = int(r.rows[0]), int(r.rows[-1])
        where = f"  # {Path(r.loc.file).name}:{r.loc.line}" if r.loc else ""
        lines.append(f"  for k in {first}..{last} ({len(r.rows)} rows of "
                     f"{', '.join(r.tables)}, compiled once):{where}")
        lines += _primitive_lines(prog.primitives.template, _RowNames(prog), "    ")
    return "\n".join(lines) + "\n"


def _primitive_lines(prims: Sequence[Primitive], names: Sequence[str], indent: str
                     ) -> list[str]:
    texts = [render_primitive(p, names) for p in prims]
    pad = min(max((len(t) for t in texts), default=0), 60)
    out = []
    for p, text in zip(prims, texts, strict=True):
        where = f"  # {Path(p.loc.file).name}:{p.loc.line}" if p.loc else ""
        out.append(f"{indent}{text:<{pad}}{where}")
    return out


class _RowNames(Sequence[str]):
    """The names of a compiled-once loop's first row, as its body reads: `t7[k]`, and a
    measured cell as `m.x[k]`."""

    def __init__(self, prog: Program) -> None:
        self.prog = prog
        assert prog.rows is not None
        self.rows = prog.rows

    def __len__(self) -> int:
        return len(self.prog.slots.lo)

    def __getitem__(self, slot: int) -> str:  # type: ignore[override]
        s = self.prog.slots
        if slot < self.rows.shared:
            return s.names[slot]
        assert isinstance(s.names, Tiled)
        j = slot - self.rows.shared
        if s.kinds[slot] == SlotKind.CONST and s.cell_col is not None and s.cell_col[slot] >= 0 \
                and s.col_keys is not None:
            table, column = s.col_keys[int(s.cell_col[slot])]
            return f"{table}.{column}[k]"
        return f"{s.names.template[j]}[k]"


def _row_variables(prog: Program) -> list[str]:
    """A compiled-once loop's per-row unknowns with a domain of their own (the measured
    sides), named as its body reads them, once for all rows."""
    r, s = prog.rows, prog.slots
    assert r is not None
    names = _RowNames(prog)
    out = []
    for j in range(r.width):
        slot = r.shared + j
        if s.kinds[slot] == SlotKind.TEMP and (s.lo[slot] > -float("inf")
                                               or s.hi[slot] < float("inf")):
            where = " (measured: its row's value and error bound)" \
                if slot in (s.measured_sides or {}) else ""
            out.append(f"  {names[slot]}  in [{_b(s.lo[slot])}, {_b(s.hi[slot])}] in row "
                       f"{int(r.rows[0])}{where}")
    return out


def listing_json(prog: Program) -> str:
    return json.dumps(prog.counts(), indent=2, allow_nan=False)


def _b(x: float) -> str:
    return format_const(x, x)
