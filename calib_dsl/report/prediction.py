"""Predictions and their validation as text, CSV and JSON (`calibc predict`, `validate`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from calib_dsl.accuracy.certified import tightness
from calib_dsl.accuracy.grid import pose_bounds
from calib_dsl.accuracy.predict import Prediction
from calib_dsl.frontend.diagnostics import CalError


def widths(p: Prediction) -> dict[str, float | None]:
    """The boxes' widths: None (JSON null) when there is no box."""
    w = (p.hi - p.lo).ravel()
    return {"median": float(np.median(w)), "max": float(np.max(w))} if w.size else \
        {"median": None, "max": None}


def tightness_of(p: Prediction) -> dict[str, Any] | None:
    """outer/inner over the predicted coordinates (None: no certified points)."""
    if p.inner_lo is None or p.inner_hi is None:
        return None
    return tightness(p.lo, p.hi, p.inner_lo, p.inner_hi)


def _inner(p: Prediction, k: int) -> dict[str, list[float] | None] | None:
    if p.inner_lo is None or p.inner_hi is None:
        return None
    return {c: None if np.isnan(p.inner_lo[k, j]) else
            [float(p.inner_lo[k, j]), float(p.inner_hi[k, j])]
            for j, c in enumerate(p.columns)}


def _tightness_line(p: Prediction) -> list[str]:
    t = tightness_of(p)
    if t is None or t["median_ratio"] is None:
        return ["outer/inner: no certified inner intervals (no certified point)"]
    return [f"outer/inner over {t['coordinates']} predicted coordinates: median "
            f"{t['median_ratio']:.3f}, worst {t['worst_ratio']:.3f} (inner: the predictions "
            "at the solve's certified points, values the model truly takes)"]


def _shown(x: float | None) -> str:
    return "none" if x is None else f"{x:.4g}"


def comparable(p: Prediction) -> None:
    """A validation needs a measured value to compare with: coverage of nothing is no
    claim, so it is a user error, never a coverage of 1."""
    if not p.columns:
        raise CalError(f"the model has no measured column for the held-out rows of {p.file}: "
                       "there is nothing to validate (a table column stated `+- bound` "
                       "that a constraint compares with is one)")
    if not p.rows:
        raise CalError(f"no held-out rows of {p.file} are left to validate on")
    if np.all(np.isnan(p.measured)):
        raise CalError(f"{p.file} holds no measured value ({', '.join(p.columns)}) in its "
                       "held-out rows: there is nothing to compare the predictions with")


def render_prediction(p: Prediction) -> str:
    head = f"{'row':>6} {'line':>6}  " + "  ".join(f"{c + ' lo':>14} {c + ' hi':>14}"
                                                    for c in p.columns)
    lines = [f"predicted measurements at {p.file}: boxes proven to hold the model's "
             "prediction for every parameter vector consistent with the data", head]
    for k, (row, line) in enumerate(zip(p.rows, p.lines, strict=True)):
        cells = "  ".join(f"{p.lo[k, j]:14.6f} {p.hi[k, j]:14.6f}" for j in range(len(p.columns)))
        lines.append(f"{row:>6} {line:>6}  {cells}")
    w = widths(p)
    lines.append(f"widths: median {_shown(w['median'])}, max {_shown(w['max'])} "
                 "(the model's units)")
    lines += _tightness_line(p)
    return "\n".join(lines)


def prediction_csv(p: Prediction) -> str:
    cols = ",".join(f"{c}_lo,{c}_hi" for c in p.columns)
    out = [f"row,line,{cols}"]
    for k, (row, line) in enumerate(zip(p.rows, p.lines, strict=True)):
        out.append(f"{row},{line}," + ",".join(f"{float(p.lo[k, j])!r},{float(p.hi[k, j])!r}"
                                               for j in range(len(p.columns))))
    return "\n".join(out) + "\n"


def prediction_json(p: Prediction) -> dict[str, Any]:
    return {"at": p.file, "columns": p.columns, "width": widths(p),
            "tightness": tightness_of(p),
            "rows": [{"row": row, "line": line,
                      **{c: [float(p.lo[k, j]), float(p.hi[k, j])]
                         for j, c in enumerate(p.columns)}, "inner": _inner(p, k)}
                     for k, (row, line) in enumerate(zip(p.rows, p.lines, strict=True))]}


def validation_json(p: Prediction) -> dict[str, Any]:
    comparable(p)
    covered = p.covered()
    return {"at": p.file, "rows": len(covered), "coverage": float(covered.mean()),
            "not_measured": not_measured(p), "width": widths(p), "tightness": tightness_of(p),
            "not_covered": [{"row": p.rows[k], "line": p.lines[k]}
                            for k in np.flatnonzero(~covered)],
            "held_out": held_out(p, covered)}


def not_measured(p: Prediction) -> list[str]:
    """The predicted columns the held-out file has no value of: not compared."""
    return [c for j, c in enumerate(p.columns) if np.all(np.isnan(p.measured[:, j]))]


def held_out(p: Prediction, covered: np.ndarray) -> list[dict[str, Any]]:
    """Per held-out row (what `calibc plot --kind prediction` draws): whether it is covered,
    and per measured column the measured value minus the predicted box, rounded outward,
    with the column's error bound."""
    with np.errstate(invalid="ignore"):
        lo = np.nextafter(p.measured - p.hi, -np.inf)
        hi = np.nextafter(p.measured - p.lo, np.inf)
    inner = [_inner(p, k) or {} for k in range(len(p.rows))]
    return [{"row": row, "line": line, "covered": bool(covered[k]),
             "columns": {c: {"error": [_num(lo[k, j]), _num(hi[k, j])],
                             "bound": float(p.bound[j]),
                             "predicted": [_num(p.lo[k, j]), _num(p.hi[k, j])],
                             "inner": inner[k].get(c),
                             "measured": float(p.measured[k, j])}
                         for j, c in enumerate(p.columns) if not np.isnan(p.measured[k, j])}}
            for k, (row, line) in enumerate(zip(p.rows, p.lines, strict=True))]


def _num(x: float) -> float | str:
    """JSON has no infinity: "-oo" and "+oo", as in the solve JSON."""
    return ("+oo" if x > 0 else "-oo") if np.isinf(x) else float(x)


def render_validation(p: Prediction) -> str:
    v = validation_json(p)
    lines = [f"validation on {v['rows']} held-out rows of {p.file}:",
             f"  coverage {v['coverage']:.4f}: rows whose every measurement lies in its "
             "predicted box widened by its error bound",
             f"  box widths: median {_shown(v['width']['median'])}, "
             f"max {_shown(v['width']['max'])} "
             "(the model's units)", *("  " + t for t in _tightness_line(p))]
    if v["not_measured"]:
        lines.insert(2, f"  not compared: {', '.join(v['not_measured'])} (no such column "
                        f"in {p.file}): the coverage is of the others")
    for r in v["not_covered"][:20]:
        lines.append(f"  not covered: {p.file}:{r['line']} (data row {r['row']})")
    if len(v["not_covered"]) > 20:
        lines.append(f"  ... and {len(v['not_covered']) - 20} more")
    return "\n".join(lines)


def grid_json(p: Prediction, poses: list[tuple[float, ...]], names: list[str]
              ) -> dict[str, Any]:
    """`predict --grid --json`: prediction_json with, per pose, its inputs (`pose`), the
    guaranteed error `bound` and `with_e` (accuracy/grid.py), and their summary."""
    bound, with_e = pose_bounds(p)
    out = prediction_json(p)
    out["inputs"] = names
    for row, pose, b, w in zip(out["rows"], poses, bound, with_e, strict=True):
        row.update(pose=dict(zip(names, pose, strict=True)), bound=_num(float(b)),
                   with_e=_num(float(w)))
    finite = bound[np.isfinite(bound)]
    out["bound"] = {"median": float(np.median(finite)) if finite.size else None,
                    "max": float(np.max(finite)) if finite.size else None,
                    "unbounded": int(len(bound) - finite.size)}
    return out


def grid_csv(doc: dict[str, Any]) -> str:
    cols, names = doc["columns"], doc["inputs"]
    out = [",".join([*names, *(f"{c}_lo,{c}_hi" for c in cols), "bound", "with_e"])]
    for r in doc["rows"]:
        cells = [*(repr(r["pose"][n]) for n in names),
                 *(repr(v) for c in cols for v in r[c]), str(r["bound"]), str(r["with_e"])]
        out.append(",".join(cells))
    return "\n".join(out) + "\n"


def render_grid(doc: dict[str, Any]) -> str:
    b = doc["bound"]
    return (f"guaranteed error bound at {len(doc['rows'])} poses of {doc['at']}: the distance "
            "from the middle of each predicted box to the prediction of any parameter vector "
            f"consistent with the data: median {_shown(b['median'])}, max {_shown(b['max'])} "
            f"(the model's units; {b['unbounded']} unbounded); per pose in --json/--csv")
