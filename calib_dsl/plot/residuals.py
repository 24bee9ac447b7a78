"""The residuals figure: per data row, the range of measured minus predicted over the result
box of each measured column (the solve JSON's `residuals`), the bound lines at +-e, the
outliers (a range wholly outside them) marked, the rows `--exclude` left out greyed."""

from __future__ import annotations

from typing import Any

from calib_dsl.plot import ranges


def supports(data: dict[str, Any]) -> bool:
    return bool(data.get("residuals", {}).get("rows"))


def count(data: dict[str, Any]) -> int:
    return len(ranges.panels(data["residuals"]["rows"], "residual", "outlier", "used"))


def draw(fig: Any, data: dict[str, Any]) -> list[Any]:
    panels = ranges.panels(data["residuals"]["rows"], "residual", "outlier", "used")
    outliers = len(data["residuals"].get("outliers", []))
    axes = ranges.draw_panels(fig, panels, "outlier (no parameter vector of the box fits it)",
                              "measured − predicted", "residuals")
    axes[0].set_title(f"residual ranges over the result box ({outliers} outlier"
                      f"{'' if outliers == 1 else 's'}; grey: rows left out)", loc="left")
    return list(axes)
