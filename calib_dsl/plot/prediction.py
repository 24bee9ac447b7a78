"""The prediction figure: per held-out row of a validation, the measured value minus the
predicted box of each column (`validate --json`'s `held_out`), the bound lines at +-e (a row
is covered when every bar meets the band between them), the rows not covered marked."""

from __future__ import annotations

from typing import Any

from calib_dsl.plot import ranges


def supports(data: dict[str, Any]) -> bool:
    return bool(data.get("held_out"))


def count(data: dict[str, Any]) -> int:
    return len(_panels(data))


def _panels(data: dict[str, Any]) -> list[ranges.Panel]:
    rows = [{**r, "not_covered": not r["covered"]} for r in data["held_out"]]
    return ranges.panels(rows, "error", "not_covered", None)


def draw(fig: Any, data: dict[str, Any]) -> list[Any]:
    axes = ranges.draw_panels(fig, _panels(data), "not covered", "measured − predicted box",
                              "prediction")
    axes[0].set_title(f"held-out rows of {data.get('at', '?')}: coverage "
                      f"{data.get('coverage', float('nan')):.3f}", loc="left")
    return list(axes)
