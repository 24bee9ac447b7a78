"""The history figure: the width of each parameter after each step and round of LPs of a
tight solve (the solve JSON's `history`) against the seconds since the solve began, on a
log scale, one panel per unit (the JSON's `unit`: no axis mixes millimetres and radians). The
parameters the solve narrowed are coloured (never grey) and named in a legend beside the
panel, however many; the others (known beforehand, or not seen by the data) are thin grey
lines."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from calib_dsl.plot.values import log_limits, number

GREY = "0.75"  # the parameters not narrowed
NAMES_PER_COLUMN = 12  # the legend's columns: beside the panel, never over a line


def supports(data: dict[str, Any]) -> bool:
    return bool(data.get("history", {}).get("steps"))


def count(data: dict[str, Any]) -> int:
    return len(_units(data))


def palette() -> list[Any]:
    """tab20 without its two greys (a grey line means: not narrowed)."""
    from matplotlib import colormaps

    tab20 = colormaps["tab20"]
    colors = [tab20(k / 19)[:3] for k in range(20)]
    return [c for c in colors if not np.allclose(c, c[0], atol=0.02)]


def _units(data: dict[str, Any]) -> dict[str, list[int]]:
    """The history's columns by unit ("" where none is known)."""
    params = data.get("parameters", {})
    out: dict[str, list[int]] = {}
    for j, name in enumerate(data["history"]["parameters"]):
        out.setdefault((params.get(name) or {}).get("unit") or "", []).append(j)
    return out


def draw(fig: Any, data: dict[str, Any]) -> list[Any]:
    h = data["history"]
    seconds = np.array([s["seconds"] for s in h["steps"]])
    widths = np.array([[number(w) for w in s["widths"]] for s in h["steps"]])
    narrowed = widths[-1] < widths[0]
    groups = _units(data)
    axes = fig.subplots(len(groups), 1, squeeze=False, sharex=True)[:, 0]
    colors = palette()
    for k, (ax, (unit, cols)) in enumerate(zip(axes, groups.items(), strict=True)):
        shown = 0
        for j in cols:
            w = np.where((widths[:, j] > 0) & np.isfinite(widths[:, j]), widths[:, j], np.nan)
            if narrowed[j]:
                ax.plot(seconds, w, marker=".", linewidth=1.2, label=h["parameters"][j],
                        color=colors[shown % len(colors)])
                shown += 1
            else:
                ax.plot(seconds, w, color=GREY, linewidth=0.8)
        ax.set_yscale("log")
        limits = log_limits(widths[:, cols])
        if limits is not None:
            ax.set_ylim(*limits)
        ax.set_ylabel(f"width ({unit})" if unit else "width")
        if shown:
            ax.legend(fontsize="x-small", loc="upper left", bbox_to_anchor=(1.01, 1.0),
                      ncols=math.ceil(shown / NAMES_PER_COLUMN), frameon=False)
        if k == 0:
            ax.set_title(f"widths step by step ({len(h['steps']) - 1} steps and rounds; "
                         f"{int(narrowed.sum())} of {len(narrowed)} parameters narrowed, the "
                         "others grey)", loc="left")
        ax.set_label("history")
    axes[-1].set_xlabel("seconds since the solve began")
    return list(axes)
