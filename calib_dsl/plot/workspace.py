"""The workspace accuracy map (`predict --grid --json`): the guaranteed error bound at each
pose against the pose's index, and the predicted positions (the middles of their boxes) in
3-D (2-D with two predicted columns) coloured by that bound: where in its workspace the
robot is guaranteed to what accuracy."""

from __future__ import annotations

from typing import Any

import numpy as np

from calib_dsl.plot.values import number


def supports(data: dict[str, Any]) -> bool:
    rows = data.get("rows")
    return bool(rows) and isinstance(rows, list) and "bound" in rows[0]


def count(data: dict[str, Any]) -> int:
    return 1


def draw(fig: Any, data: dict[str, Any]) -> list[Any]:
    rows, cols = data["rows"], data["columns"]
    bound = np.array([number(r["bound"]) for r in rows], dtype=float)
    mid = np.array([[0.5 * (number(r[c][0]) + number(r[c][1])) for c in cols[:3]]
                    for r in rows], dtype=float)
    spatial = len(cols) >= 2
    index = fig.add_subplot(1, 2 if spatial else 1, 1)
    index.plot(np.arange(1, len(bound) + 1), bound, ".", markersize=3, color="tab:blue")
    index.set_xlabel("pose")
    index.set_ylabel("guaranteed error bound")
    b = data.get("bound", {})
    index.set_title(f"{len(rows)} poses: bound median {number(b.get('median')):.3g}, "
                    f"max {number(b.get('max')):.3g}", loc="left", fontsize="small")
    index.set_label("workspace")
    axes = [index]
    if spatial:
        three = len(cols) >= 3
        ax = fig.add_subplot(1, 2, 2, projection="3d" if three else None)
        dots = ax.scatter(*(mid[:, j] for j in range(3 if three else 2)), c=bound, s=6,
                          cmap="viridis")
        ax.set_xlabel(cols[0])
        ax.set_ylabel(cols[1])
        if three:
            ax.set_zlabel(cols[2])
        fig.colorbar(dots, ax=ax, label="bound", shrink=0.8)
        ax.set_label("workspace:positions")
        axes.append(ax)
    return axes
