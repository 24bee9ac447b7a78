"""The domains figure: per parameter, the width of its search domain, of its guaranteed
result and of its certified inner interval when the solve computed one (bars on a log scale:
they span orders of magnitude), and beside it where the true value lies in the result, when
the model gives one (-1: its lower end, +1: its upper end)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from calib_dsl.plot.values import number, width

OUTSIDE = 1.5  # a true value outside the result is drawn here, in red


def supports(data: dict[str, Any]) -> bool:
    return bool(data.get("parameters"))


def count(data: dict[str, Any]) -> int:
    return len(data["parameters"])


def draw(fig: Any, data: dict[str, Any]) -> list[Any]:
    params = data["parameters"]
    names = list(params)
    y = np.arange(len(names))
    domain = np.array([width(p["domain"]) for p in params.values()])
    result = np.array([width(p["result"]) for p in params.values()])
    has_true = any(p["true"] is not None and p["result"] is not None for p in params.values())
    axes = fig.subplots(1, 2 if has_true else 1, squeeze=False, sharey=True,
                        gridspec_kw={"width_ratios": [3, 1]} if has_true else None)[0]
    ax = axes[0]
    shown = np.isfinite(domain) & (domain > 0)
    ax.barh(y[shown], domain[shown], height=0.8, color="0.8", label="search domain")
    shown = np.isfinite(result) & (result > 0)
    ax.barh(y[shown], result[shown], height=0.45, color="C0", label="guaranteed result")
    inner = np.array([width(p["inner"]) if p.get("inner") else np.nan
                      for p in params.values()])
    shown = np.isfinite(inner) & (inner > 0)
    if np.any(shown):  # how much of the result is proven real
        ax.barh(y[shown], inner[shown], height=0.15, color="C1", label="certified inner")
    ax.set_xscale("log")
    ax.set_yticks(y, names, fontsize="small")
    ax.invert_yaxis()
    ax.set_xlabel("width (the model's units, log scale)")
    ax.set_title(f"{data.get('model', '')}: search domains and results", loc="left")
    ax.legend(fontsize="small", loc="lower right")
    ax.set_label("domains")
    if has_true:
        _truth(axes[1], params, y)
    return list(axes)


def _truth(ax: Any, params: dict[str, Any], y: np.ndarray) -> None:
    """Where each true value lies in its result, scaled to [-1, 1]."""
    xs, ys, outside = [], [], []
    for k, p in enumerate(params.values()):
        if p["true"] is None or p["result"] is None:
            continue
        lo, hi = (number(v) for v in p["result"])
        mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
        inside = lo <= p["true"] <= hi
        x = 0.0 if half == 0 or not math.isfinite(half) else (p["true"] - mid) / half
        xs.append(x if inside else math.copysign(OUTSIDE, p["true"] - mid))
        ys.append(y[k])
        outside.append(not inside)
    ax.axvspan(-1, 1, color="C0", alpha=0.15, label="result")
    colors = ["red" if o else "black" for o in outside]
    ax.scatter(xs, ys, c=colors, marker="|" if not any(outside) else "o", s=80,
               label="true value")
    ax.set_xlim(-OUTSIDE - 0.3, OUTSIDE + 0.3)
    ax.set_xticks([-1, 0, 1])
    ax.set_xlabel("true value in the result")
    ax.set_title(f"true values: {sum(outside)} outside", loc="left", fontsize="small")
    ax.set_label("domains:true")
