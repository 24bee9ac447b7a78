"""Intervals of measured minus predicted per data row, against the error bound: what the
residuals and the held-out prediction figures share.

Each measured column is one LineCollection of vertical bars (one per row, side by side
within a row), the bound is a dashed line at +e and one at -e, and the rows to notice (an
outlier, a held-out row outside its box) are red crosses on their bars. Columns with
different bounds (millimetres and radians) get an axes each: one scale would hide one."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from calib_dsl.plot.values import number

CLIP = 20.0  # an unbounded end is drawn at CLIP e, or beyond every finite end


@dataclass
class Panel:
    """Rows (their numbers), per column the ranges (nan: none), its bound e, and per row
    whether to mark it and whether to grey it (a row the solve did not use)."""

    rows: np.ndarray
    ranges: dict[str, tuple[np.ndarray, np.ndarray]]
    bound: float
    marked: np.ndarray
    greyed: np.ndarray


def panels(rows: list[dict[str, Any]], key: str, marked: str, used: str | None
           ) -> list[Panel]:
    """The rows of a result JSON (each with `row`, `columns`: {name: {key: [lo, hi],
    "bound": e}}, and the flags `marked` and `used`) as one panel per distinct bound."""
    numbers = np.array([r["row"] for r in rows], dtype=float)
    columns: dict[str, float] = {}
    for r in rows:  # a column's bound, to 3 digits: outward rounding makes cells differ
        for name, cell in r["columns"].items():
            columns.setdefault(name, float(f"{float(cell['bound']):.3g}"))
    out: dict[float, Panel] = {}
    for name, e in columns.items():
        lo, hi = np.full(len(rows), np.nan), np.full(len(rows), np.nan)
        for i, r in enumerate(rows):
            cell = r["columns"].get(name)
            if cell is not None:
                lo[i], hi[i] = (number(v) for v in cell[key])
        panel = out.setdefault(e, Panel(
            numbers, {}, e, np.array([bool(r[marked]) for r in rows]),
            np.array([used is not None and not r[used] for r in rows])))
        panel.ranges[name] = (lo, hi)
    return list(out.values())


def draw(ax: Any, panel: Panel, mark_label: str) -> None:
    n = len(panel.ranges)
    width = 0.8 * _spacing(panel.rows)
    ends = np.concatenate([np.abs(np.concatenate(r)) for r in panel.ranges.values()])
    lim = max([CLIP * panel.bound, *ends[np.isfinite(ends)]])
    crosses: list[tuple[float, float]] = []
    for j, (name, (lo, hi)) in enumerate(panel.ranges.items()):
        x = panel.rows + (j - (n - 1) / 2) * width / max(n, 1)
        ok = ~np.isnan(lo)
        lo, hi = np.clip(lo, -lim, lim), np.clip(hi, -lim, lim)
        ax.vlines(x[ok], lo[ok], hi[ok], colors=f"C{j % 10}", linewidth=1.5, label=name)
        with np.errstate(invalid="ignore"):  # a cross on each bar wholly outside +-e
            out = panel.marked & ((lo > panel.bound) | (hi < -panel.bound))
        crosses += zip(x[out], 0.5 * (lo[out] + hi[out]), strict=True)
    for sign in (1, -1):
        ax.axhline(sign * panel.bound, color="black", linestyle="--", linewidth=0.8,
                   label=f"±e = ±{panel.bound:.3g}" if sign > 0 else None)
    if crosses:
        xs, ys = zip(*crosses, strict=True)
        ax.plot(xs, ys, "x", color="red", markersize=8, label=mark_label)
    for x in panel.rows[panel.greyed]:
        ax.axvspan(x - width / 2, x + width / 2, color="0.85", zorder=0)
    ax.set_xlabel("data row")
    ax.xaxis.get_major_locator().set_params(integer=True)
    # beside the axes: over them it would hide bars
    ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.0, 1.0))


def _spacing(rows: np.ndarray) -> float:
    gaps = np.diff(np.unique(rows))
    return float(gaps.min()) if len(gaps) else 1.0



def draw_panels(fig: Any, panels: list[Panel], marked: str, ylabel: str,
                label: str) -> list[Any]:
    """One axes per panel, stacked: the ranges, `marked` naming the marked rows."""
    axes = fig.subplots(len(panels), 1, squeeze=False)[:, 0]
    for ax, panel in zip(axes, panels, strict=True):
        draw(ax, panel, marked)
        ax.set_ylabel(ylabel)
        ax.set_label(label)
    return list(axes)
