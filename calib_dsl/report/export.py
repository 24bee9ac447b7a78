"""A result exported for the next run or for a controller (`calibc export`, `solve
--export-domains`): from a solve's JSON (or the same data in memory).

- `cal`: `param NAME in [lo, hi];` lines, the result as search domains for the next run. The
  language reads a decimal bound outward (the nearest float below a lower bound, above an
  upper one), so each bound is the shortest decimal that reads back as the result's float
  exactly: the domain read is the result, not a float wider.
- `json`, `dh-table`: each value at the exported point (report/export_point.py: the
  midpoint by default, as a short decimal) and a guaranteed half-width (the exact distance to
  the farther end of the enclosure, rounded up to 3 significant digits): every value consistent
  with the data lies within value +- half-width, in the model's units.
"""

from __future__ import annotations

import math
from decimal import ROUND_CEILING, ROUND_FLOOR, Context, Decimal
from fractions import Fraction
from typing import Any

from calib_dsl.report.decimals import clean
from calib_dsl.studies.robot_frames import FrameRow, RobotTable

NOTE = ("value: the midpoint of the guaranteed enclosure; half_width: rounded up, so that "
        "every value consistent with the data lies within value +- half_width")


def number(v: Any) -> float:
    """A bound as the result JSON writes it ("-oo", "+oo" for unbounded ends)."""
    return {"-oo": -math.inf, "+oo": math.inf}[v] if isinstance(v, str) else float(v)


def text(x: float) -> str:
    """A float as the language reads it back exactly (repr), infinities as -oo / +oo."""
    if math.isinf(x):
        return "+oo" if x > 0 else "-oo"
    return repr(float(x))


def bound_text(x: float, lower: bool) -> str:
    """The shortest decimal that the language, reading it outward as a lower (or upper)
    bound, turns back into x exactly: x <= D < the next float up (or the reverse)."""
    if math.isinf(x) or x == 0:
        return text(x)
    exact, beyond = Decimal(x), Decimal(math.nextafter(x, math.inf if lower else -math.inf))
    for digits in range(1, 18):
        d = Context(prec=digits, rounding=ROUND_CEILING if lower else ROUND_FLOOR).plus(exact)
        if (d < beyond) if lower else (d > beyond):
            return str(d)
    return str(exact)  # (a float's exact decimal: read back as itself)


def interval_text(lo: float, hi: float) -> str:
    """`[lo, hi]` as the language reads it back exactly (a point, or two floats next to each
    other, as their exact decimals: the shortest ones could cross)."""
    a, b = bound_text(lo, True), bound_text(hi, False)
    if "oo" not in a + b and Decimal(a) > Decimal(b):
        a, b = str(Decimal(lo)), str(Decimal(hi))
    return f"[{a}, {b}]"


# -- cal: the result as the next run's search domains ------------------------------------------
def domains_cal(data: dict[str, Any]) -> str:
    """`param`/`var` declarations whose domains hold the result of the solve JSON `data`;
    a family's elements share one domain (the hull of theirs), each narrowed to its own
    result by a constraint."""
    lines = [f"# Search domains from the guaranteed result of calibc solve {data.get('model')}",
             "# (include this file in place of the model's own declarations; every interval "
             "holds the result)"]
    families: dict[str, list[tuple[str, dict[str, Any]]]] = {}
    for name, p in data["parameters"].items():
        if p["result"] is None:
            raise ValueError("an infeasible result has no domains to export")
        if "[" in name:
            families.setdefault(name.split("[")[0], []).append((name, p))
            continue
        lo, hi = (number(v) for v in p["result"])
        true = p["true"]
        keep = true is not None and lo <= true <= hi  # a true value must lie in the domain
        lines.append(f"{p['kind']} {name} in {interval_text(lo, hi)}"
                     f"{' true ' + text(true) if keep else ''};")
    for base, members in families.items():
        lines += _family(base, members)
    return "\n".join(lines) + "\n"


def _family(base: str, members: list[tuple[str, dict[str, Any]]]) -> list[str]:
    index = [tuple(int(i) for i in name[len(base) + 1:-1].split("][")) for name, _ in members]
    dims = "".join(f"[{min(ix[d] for ix in index)}..{max(ix[d] for ix in index)}]"
                   for d in range(len(index[0])))
    los = [number(p["result"][0]) for _, p in members]
    his = [number(p["result"][1]) for _, p in members]
    out = [f"{members[0][1]['kind']} {base}{dims} in {interval_text(min(los), max(his))};"]
    out += [f"{name} == {interval_text(lo, hi)};"
            for (name, _), lo, hi in zip(members, los, his, strict=True)]
    return out


# -- midpoint +- guaranteed half-width --------------------------------------------------------
def plus_minus(lo: float, hi: float, mid: float | None = None) -> tuple[float, str]:
    """The midpoint (or `mid`, a point inside) and the half-width around it, rounded up to 3
    significant digits, as text: it covers [lo, hi] around the float and around its repr
    read as a decimal alike."""
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return (0.5 * lo + 0.5 * hi if math.isfinite(lo + hi) else math.nan), "oo"
    m = 0.5 * lo + 0.5 * hi if mid is None else mid
    h = max(max(c - Fraction(lo), Fraction(hi) - c) for c in (Fraction(m), Fraction(repr(m))))
    return m, _up3(max(h, Fraction(0)))


def _up3(h: Fraction) -> str:
    if h == 0:
        return "0"
    up = Context(prec=60, rounding=ROUND_CEILING)
    d = up.divide(Decimal(h.numerator), Decimal(h.denominator))
    return f"{Context(prec=3, rounding=ROUND_CEILING).plus(d):.2e}"  # exact: 3 digits


def half_float(h: str) -> float | str:
    """A half-width text as a JSON number no smaller than it ("oo" stays a string)."""
    if h == "oo":
        return "+oo"
    x = float(h)
    return float(math.nextafter(x, math.inf)) if Fraction(x) < Fraction(h) else x


def value_json(lo: float, hi: float, unit: str | None, mid: float | None = None,
               nominal: bool = False) -> dict[str, Any]:
    m, h = plus_minus(lo, hi, None if mid is None else float(clean(mid)))
    out: dict[str, Any] = {"value": m, "half_width": half_float(h), "nominal": nominal}
    if unit is not None:
        out["unit"] = unit
    return out


def units_of(tables: list[RobotTable], units: dict[str, str]) -> dict[str, str]:
    """The unit of each parameter that is the only one a frame entry reads (an offset, a
    length); the others' units are not known here (a tool point's coordinates)."""
    out: dict[str, str] = {}
    for t in tables:
        for f in t.frames:
            for e in f.entries:
                if len(e.reads) == 1:
                    out.setdefault(e.reads[0], units[e.dimension])
    return out


def export_json(data: dict[str, Any], tables: list[RobotTable], units: dict[str, str],
                param_units: dict[str, str], point: dict[str, float] | None = None
                ) -> dict[str, Any]:
    point = point or {}
    params = {name: value_json(number(p["result"][0]), number(p["result"][1]),
                               param_units.get(name), point.get(name))
              for name, p in data["parameters"].items()}
    robots = [{"name": t.name, "frames": [_frame_json(f, units) for f in t.frames]}
              for t in tables]
    return {"model": data.get("model"), "units": units, "note": NOTE, "parameters": params,
            "robots": robots}


def _frame_json(f: FrameRow, units: dict[str, str]) -> dict[str, Any]:
    return {"part": f.part, "number": f.number, "convention": f.convention,
            "motion": f.motion, "joint": f.joint, "axis": f.axis,
            "entries": {e.name: value_json(e.lo, e.hi, units[e.dimension], e.mid,
                                           not e.reads) for e in f.entries}}


# -- the DH table ------------------------------------------------------------------------------
CONVENTIONS = {
    "mdh": "modified DH (Khalil-Kleinfinger): frame j-1 -> j = Rx(alpha) Tx(d) Rz(theta) Tz(r)",
    "dh": "standard DH: frame j-1 -> j = Rz(theta) Tz(d) Tx(a) Rx(alpha)",
    "xyz": "6-DOF frames: T(x, y, z) Rx(rx) Ry(ry) Rz(rz) (X-Y-Z Euler angles)",
}


def dh_table(data: dict[str, Any], tables: list[RobotTable], units: dict[str, str]) -> str:
    out = [f"# DH tables of the robots of {data.get('model')}, from its guaranteed result",
           "# each entry: its value at the exported point (--point), then '+-' its "
           "half-width (rounded up): every value consistent with the data lies within; "
           "'nominal': fixed by the model, not calibrated",
           f"# lengths in {units['length']}, angles in {units['angle']}; entries at q = 0: "
           "a revolute joint's variable adds to theta, a prismatic one's to r (MDH) or d (DH)"]
    for t in tables:
        out.append(f"\nrobot {t.name}")
        for convention in dict.fromkeys(f.convention for f in t.frames):
            out += _block(t, convention)
    return "\n".join(out) + "\n"


def _block(t: RobotTable, convention: str) -> list[str]:
    frames = [f for f in t.frames if f.convention == convention]
    names = [e.name for e in frames[0].entries]
    header = ["frame", "motion"] + [c for n in names for c in (n, "+-")]
    rows = [header]
    for f in frames:
        motion = f.motion if f.axis > 0 else f"{f.motion}(-q)"
        row = [f"{f.part}{f.number}", motion]
        for n in names:
            e = f.entry(n)
            m, h = plus_minus(e.lo, e.hi, float(clean(e.mid)))
            row += [clean(m), "nominal" if not e.reads else h]
        rows.append(row)
    widths = [max(len(r[i]) for r in rows) for i in range(len(header))]
    return [f"# {CONVENTIONS[convention]}"] + [
        "  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in rows]
