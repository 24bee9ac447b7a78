"""The accuracy figure: histograms of the per-pose distances between measurement and
prediction before calibration (nominal) and after (least squares, certified centre), from the
solve JSON's `accuracy`, with the guaranteed bound over the poses (its largest value, and its
median dashed) as vertical lines."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from calib_dsl.plot.values import number

BINS = 40  # shared by every histogram: their bars compare bin by bin
LABELS = {"nominal": "before (nominal)", "least_squares": "after (least squares)",
          "certified": "after (certified centre)"}
COLOURS = {"nominal": "tab:red", "least_squares": "tab:blue", "certified": "tab:green"}


def supports(data: dict[str, Any]) -> bool:
    return bool(data.get("accuracy", {}).get("points"))


def count(data: dict[str, Any]) -> int:
    return 1


def draw(fig: Any, data: dict[str, Any]) -> list[Any]:
    acc = data["accuracy"]
    found = {k: np.array([_value(d) for d in p["distances"]], dtype=float)
             for k, p in acc["points"].items()}
    found = {k: d[np.isfinite(d)] for k, d in found.items()}
    bound = acc["bound"]
    top = [_value(bound["max"])]
    ends = np.concatenate([*found.values(), [t for t in top if np.isfinite(t)]])
    edges = np.linspace(0.0, float(np.max(ends)) if len(ends) and np.max(ends) > 0 else 1.0,
                        BINS + 1)
    ax = fig.subplots()
    for k, d in found.items():
        ax.hist(d, bins=edges, histtype="stepfilled" if k == "nominal" else "step",
                alpha=0.35 if k == "nominal" else 1.0, linewidth=1.5, color=COLOURS.get(k),
                label=f"{LABELS.get(k, k)}: rms {np.sqrt(np.mean(d ** 2)):.3g}" if len(d)
                else LABELS.get(k, k))
    if np.isfinite(top[0]):
        ax.axvline(top[0], color="black", linewidth=1.5,
                   label=f"guaranteed bound, largest over poses: {top[0]:.3g}")
        ax.axvline(number(bound["median"]), color="black", linestyle="--", linewidth=1.0,
                   label=f"guaranteed bound, median: {number(bound['median']):.3g}")
    unit = acc.get("unit") or "the model's length unit"
    ax.set_xlabel(f"distance between measurement and prediction per pose ({unit})")
    ax.set_ylabel("poses")
    none = "" if np.isfinite(top[0]) else " (some pose has no finite guaranteed bound)"
    ax.set_title(f"accuracy over the data's {acc['configurations']} poses{none}", loc="left")
    ax.legend(fontsize="x-small", loc="upper right")
    ax.set_label("accuracy")
    return [ax]


def _value(v: Any) -> float:
    """A JSON number of the result (null: none, nan)."""
    return math.nan if v is None else number(v)
