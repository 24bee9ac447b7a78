"""What the report says, section by section, as plain data for the template: each number
printed at the precision its guarantee supports (report/decimals.py), with the JSON value it
came from kept beside it (the template writes it as a `data-json` attribute: a test compares
them)."""

from __future__ import annotations

import math
from collections import Counter
from typing import Any

from calib_dsl.handover.documents import Documents
from calib_dsl.report import decimals as nb

VERDICTS = {
    "consistent": "The data are consistent with the model: a parameter vector is proven to "
                  "satisfy every measurement within its error bound.",
    "inconsistent": "The data are inconsistent with the model: no parameter vector within "
                    "the search domains satisfies every measurement within its error bound.",
    "undecided": "Undecided: the solve could neither certify a parameter vector nor prove "
                 "the data inconsistent; the intervals below hold every solution, but there "
                 "may be none.",
}


def verdict(docs: Documents) -> dict[str, Any]:
    r = docs.result
    decision = r.get("decision") or {}
    return {"verdict": r["verdict"], "sentence": VERDICTS.get(r["verdict"], r["verdict"]),
            "reason": decision.get("reason"), "next": decision.get("next"),
            "bounds": bounds(r), "rows": rows(r)}


def bounds(r: dict[str, Any]) -> list[str]:
    """The error bounds the solve used, per measured column (`x, y, z: +- 1.0`)."""
    found: dict[str, list[str]] = {}
    for row in (r.get("residuals") or {}).get("rows", []):
        for col, c in row.get("columns", {}).items():
            names = found.setdefault(nb.plain(c["bound"]), [])
            if col not in names:
                names.append(col)
    return [f"{', '.join(cols)}: ±{b}" for b, cols in found.items()]


def rows(r: dict[str, Any]) -> dict[str, Any]:
    """The rows used and those left out, by the provenance and the residuals."""
    data = (r.get("provenance") or {}).get("data", [])
    res = (r.get("residuals") or {}).get("rows", [])
    out = r.get("outliers") or {}
    return {"used": sum(d.get("rows") or 0 for d in data) or sum(x["used"] for x in res),
            "left_out": sum(not x["used"] for x in res),
            "certain": out.get("certain", []), "possible": out.get("possible", [])}


def parameters(r: dict[str, Any]) -> list[dict[str, Any]]:
    """One row per unknown, in the result's order."""
    out = []
    for name, p in r["parameters"].items():
        dom = [nb.number(v) for v in p["domain"]]
        res = None if p["result"] is None else [nb.number(v) for v in p["result"]]
        inner = [nb.number(v) for v in p["inner"]] if p.get("inner") else None
        out.append({
            "name": name, "unit": p.get("unit") or "", "json": p,
            "domain": nb.outward(*dom),
            "result": None if res is None else nb.outward(*res),
            "inner": None if inner is None else nb.inward(*inner),
            "ratio": _ratio(res, inner),
            "value": None if res is None else nb.plus_minus(*res),
            "status": _status(name, dom, res, r),
        })
    return out


def _ratio(res: list[float] | None, inner: list[float] | None) -> str:
    if res is None or inner is None:
        return ""
    w = inner[1] - inner[0]
    return nb.ratio(math.inf if w == 0 else (res[1] - res[0]) / w)


def _status(name: str, dom: list[float], res: list[float] | None, r: dict[str, Any]) -> str:
    if res is None:
        return "no solution"
    if res == dom:
        return "whole domain"
    shaved = name in (r.get("shaved") or {}).get("parameters", [])
    return "narrowed, shaved" if shaved else "narrowed"


def unidentified(docs: Documents) -> list[dict[str, Any]]:
    """What the data could not identify, and what absorbs it."""
    info = docs.result.get("identifiability") or {}
    combos = {c["combination"]: c["result"] for c in info.get("combinations", [])}
    out = [{"parameters": g["parameters"], "by": None, "seen": [
        {"combination": c, "json": combos.get(c),
         "result": nb.outward(*map(nb.number, combos[c])) if c in combos else None}
        for c in g.get("identifiable_combinations", [])]}
        for g in info.get("not_identifiable", [])]
    for g in (docs.identify or {}).get("absorbed", []):
        out.append({"parameters": g["parameters"], "by": g.get("move_with"), "seen": []})
    return out


def accuracy(docs: Documents) -> dict[str, Any]:
    """The accuracy statement: guaranteed errors on held-out poses when a validation was run,
    else the deviations the result box allows on the data's own poses."""
    v = docs.validation
    if v is not None:
        widths = v.get("width") or {}
        return {"kind": "validation", "at": v.get("at"), "rows": v.get("rows"),
                "coverage": nb.plain(v.get("coverage")),
                "not_covered": len(v.get("not_covered", [])),
                "median": nb.plain(widths.get("median")), "worst": nb.plain(widths.get("max")),
                "json": {"coverage": v.get("coverage"), "median": widths.get("median"),
                         "worst": widths.get("max")}}
    stated = docs.result.get("accuracy")
    if stated and stated.get("bound"):
        return statement(stated)
    res = (docs.result.get("residuals") or {}).get("rows", [])
    used = [x for x in res if x["used"]]
    if not used:
        return {"kind": "none"}
    worst = [max(max(abs(nb.number(e)) for e in c["residual"]) for c in x["columns"].values())
             for x in used]
    worst.sort()
    return {"kind": "data", "rows": len(used), "median": nb.plain(_median(worst)),
            "worst": nb.plain(worst[-1]),
            "json": {"median": _median(worst), "worst": worst[-1]}}


POINTS = (("nominal", "before calibration (nominal)"),
          ("least_squares", "after: the least-squares point"),
          ("certified", "after: the certified point"))


def statement(a: dict[str, Any]) -> dict[str, Any]:
    """The solve's own accuracy statement (its JSON `accuracy`): residual distances before
    and after calibration (statistics), and the guaranteed bound (a proof)."""
    rows = []
    for key, label in POINTS:
        d = (a.get("points", {}).get(key) or {}).get("distance")
        if d:
            rows.append({"label": label, "json": d,
                         **{k: nb.plain(d.get(k)) for k in ("mean", "rms", "p95", "max")}})
    bound = a["bound"]
    return {"kind": "statement", "rows": rows, "configurations": a.get("configurations"),
            "median": nb.plain(bound.get("median")), "worst": nb.plain(bound.get("max")),
            "json": {"median": bound.get("median"), "worst": bound.get("max")},
            "columns": ", ".join(a.get("distance_columns") or a.get("columns") or [])}


def _median(xs: list[float]) -> float:
    n = len(xs)
    return xs[n // 2] if n % 2 else 0.5 * (xs[n // 2 - 1] + xs[n // 2])


def data(docs: Documents) -> dict[str, Any]:
    prov = docs.result.get("provenance") or {}
    files = [{"table": d["table"], "path": d["path"], "sha256": d["sha256"], "rows": d["rows"]}
             for d in prov.get("data", [])]
    res = (docs.result.get("residuals") or {}).get("rows", [])
    outlying = Counter(x["outlier"] for x in res)
    bracket = None
    if docs.min_error is not None:
        lo, hi = (nb.number(v) for v in docs.min_error["bracket"])
        shown = nb.outward(0.0 if math.isnan(lo) else lo, math.inf if math.isnan(hi) else hi)
        bracket = {"name": docs.min_error.get("name"), "json": docs.min_error["bracket"],
                   # (null: no value below was proven inconsistent, or none above consistent)
                   "shown": ("0" if math.isnan(lo) else shown[0],
                             "+oo" if math.isnan(hi) else shown[1])}
    return {"files": files, "outliers_of_result": outlying.get(True, 0),
            "rows_checked": len(res), "bracket": bracket}


def provenance(docs: Documents) -> dict[str, Any]:
    prov = docs.result.get("provenance") or {}
    return {**prov, "documents": list(docs.names), "solve_seconds": nb.plain(
        docs.result.get("seconds"), 3)}
