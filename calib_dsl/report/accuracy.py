"""The solve's accuracy statement (accuracy/statement.py): the JSON's `accuracy` and the text
report's section."""

from __future__ import annotations

from typing import Any

import numpy as np

from calib_dsl.accuracy.statement import Accuracy, distances, statistics

# the points, in the order reported, and how the text names them
POINTS = {"nominal": "before (nominal)", "least_squares": "after (least squares)",
          "certified": "after (certified centre)"}


def accuracy_json(acc: Accuracy, unit: str | None) -> dict[str, Any]:
    """`unit`, `columns`, `configurations`; per point its per-axis and distance statistics
    and per-configuration distances; `bound`, the guaranteed distance bound (docs/json.md)."""
    points = {}
    for label in POINTS:
        if label not in acc.points:
            continue
        r = acc.points[label]
        d = distances(r, acc.among)
        points[label] = {
            "axes": {c: statistics(r[:, j], signed=True) for j, c in enumerate(acc.at.columns)},
            "distance": statistics(d), "distances": d}
    finite = acc.bound[np.isfinite(acc.bound)]
    return {"unit": unit, "columns": list(acc.at.columns),
            "distance_columns": [c for c, k in zip(acc.at.columns, acc.among, strict=True) if k],
            "configurations": len(acc.at.configurations), "points": points,
            "bound": {"max": float(np.max(acc.bound)) if len(acc.bound) else None,
                      "median": float(np.median(acc.bound)) if len(acc.bound) else None,
                      "unbounded": int(len(acc.bound) - len(finite)),
                      "axes": {c: float(np.nanmax(acc.worst[:, j])) if len(acc.worst) else None
                               for j, c in enumerate(acc.at.columns)},
                      "distances": acc.bound,
                      "box_max": float(np.max(acc.box_bound)) if len(acc.bound) else None,
                      "box_median": float(np.median(acc.box_bound)) if len(acc.bound)
                      else None}}


def render_accuracy(found: dict[str, Any]) -> list[str]:
    unit = found["unit"] or "the model's length unit"
    cols = found["columns"]
    lines = [f"accuracy over the data's {found['configurations']} configurations "
             f"(measured minus predicted, in {unit}; distance: the norm over "
             f"{', '.join(found['distance_columns'])}):",
             f"  {'':34s} {'mean':>9s} {'rms':>9s} {'p95':>9s} {'max':>9s}"]
    for label, point in found["points"].items():
        lines.append(f"  {POINTS[label] + ' distance':34s} {_row(point['distance'])}")
        for c in cols:
            lines.append(f"  {'  ' + c:34s} {_row(point['axes'][c])}")
    b = found["bound"]
    sep = f" {found['unit']} " if found["unit"] else " "
    if b["max"] is not None:
        lines.append(f"  guaranteed: every consistent parameter vector predicts each of these "
                     f"poses within {_num(b['max'])}{sep}of its measurement (median over "
                     f"poses {_num(b['median'])}); every vector of the result box, consistent "
                     f"or not, within {_num(b['box_max'])}")
    return lines


def _row(s: dict[str, float | None]) -> str:
    return " ".join(f"{_num(s[k]):>9s}" for k in ("mean", "rms", "p95", "max"))


def _num(x: float | None) -> str:
    return "-" if x is None else f"{x:.4g}"
