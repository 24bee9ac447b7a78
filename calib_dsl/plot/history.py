"""The history figure: the width of each parameter after each step and round of LPs of a
tight solve (the solve JSON's `history`) against the seconds since the solve began, on a
log scale. The parameters the solve narrowed are coloured and named; the others (known
beforehand, or not seen by the data) are thin grey lines."""

from __future__ import annotations

from typing import Any

import numpy as np

from calib_dsl.plot.values import number

LEGEND_MAX = 20  # more names than this: the legend would hide the lines


def supports(data: dict[str, Any]) -> bool:
    return bool(data.get("history", {}).get("steps"))


def count(data: dict[str, Any]) -> int:
    return 1


def draw(fig: Any, data: dict[str, Any]) -> list[Any]:
    h = data["history"]
    seconds = np.array([s["seconds"] for s in h["steps"]])
    widths = np.array([[number(w) for w in s["widths"]] for s in h["steps"]])
    ax = fig.subplots()
    narrowed = widths[-1] < widths[0]
    for j, name in enumerate(h["parameters"]):
        w = np.where((widths[:, j] > 0) & np.isfinite(widths[:, j]), widths[:, j], np.nan)
        if narrowed[j]:
            ax.plot(seconds, w, marker=".", linewidth=1.2, label=name)
        else:
            ax.plot(seconds, w, color="0.75", linewidth=0.8)
    ax.set_yscale("log")
    ax.set_xlabel("seconds since the solve began")
    ax.set_ylabel("width")
    ax.set_title(f"widths step by step ({len(h['steps']) - 1} steps and rounds; "
                 f"{int(narrowed.sum())} of {len(narrowed)} parameters narrowed, the others "
                 "grey)", loc="left")
    if 0 < narrowed.sum() <= LEGEND_MAX:
        ax.legend(fontsize="x-small", ncols=2 if narrowed.sum() > 8 else 1,
                  loc="upper right")
    ax.set_label("history")
    return [ax]

