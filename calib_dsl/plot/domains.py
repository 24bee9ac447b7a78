"""The domains figure: per parameter, the width of its search domain, of its guaranteed
result and of its certified inner interval when the solve computed one (bars on a log scale:
they span orders of magnitude), one panel per unit (the JSON's `unit`), and beside it where the
true value lies in the result, when the model gives one (-1: its lower end, +1: its upper
end)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from calib_dsl.plot.values import log_limits, number, width

OUTSIDE = 1.5  # a true value outside the result is drawn here, in red


def supports(data: dict[str, Any]) -> bool:
    return bool(data.get("parameters"))


def count(data: dict[str, Any]) -> int:
    return len(data["parameters"]) + 2 * len(units(data["parameters"]))  # + titles, axes


def units(params: dict[str, Any]) -> dict[str, list[str]]:
    """The unknowns by unit ("" where the model says none): one panel each, so that no axis
    mixes millimetres and radians."""
    out: dict[str, list[str]] = {}
    for name, p in params.items():
        out.setdefault(p.get("unit") or "", []).append(name)
    return out


def draw(fig: Any, data: dict[str, Any]) -> list[Any]:
    params = data["parameters"]
    groups = units(params)
    has_true = any(p["true"] is not None and p["result"] is not None for p in params.values())
    axes = fig.subplots(len(groups), 2 if has_true else 1, squeeze=False,
                        gridspec_kw={"height_ratios": [len(g) + 2 for g in groups.values()],
                                     **({"width_ratios": [3, 1]} if has_true else {})})
    for k, (unit, names) in enumerate(groups.items()):
        ax = axes[k, 0]
        _widths(ax, {n: params[n] for n in names}, unit)
        if k == 0:
            ax.set_title(f"{data.get('model', '')}: search domains and results", loc="left")
            # above the panel, never over a bar
            ax.legend(fontsize="small", loc="lower left", bbox_to_anchor=(0.0, 1.08),
                      ncols=3, frameon=False)
        if has_true:
            _truth(axes[k, 1], {n: params[n] for n in names}, np.arange(len(names)))
            axes[k, 1].set_visible(any(params[n]["true"] is not None for n in names))
    return list(axes.ravel())


def _widths(ax: Any, params: dict[str, Any], unit: str) -> None:
    names = list(params)
    y = np.arange(len(names))
    drawn = []
    for key, height, color, label in (("domain", 0.8, "0.8", "search domain"),
                                      ("result", 0.45, "C0", "guaranteed result"),
                                      ("inner", 0.15, "C1", "certified inner")):
        w = np.array([width(p.get(key)) if p.get(key) else np.nan for p in params.values()])
        shown = np.isfinite(w) & (w > 0)
        if np.any(shown):
            ax.barh(y[shown], w[shown], height=height, color=color, label=label)
            drawn += list(w[shown])
    ax.set_xscale("log")
    limits = log_limits(drawn)
    if limits is not None:
        ax.set_xlim(*limits)
    ax.set_yticks(y, names, fontsize="small")
    ax.set_ylim(len(names) - 0.5, -0.5)
    ax.set_xlabel(f"width ({unit or 'the model says no unit'}, log scale)")
    ax.set_label("domains")


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
    ax.set_yticks(y, [])
    ax.set_ylim(len(y) - 0.5, -0.5)
    ax.set_label("domains:true")
