"""The prediction figure: a validation's held-out rows (`validate --json`'s `held_out`)
each measured column's interval of measured minus predicted drawn as a band over the rows
sorted by the column's guaranteed error (the larger size of the interval's ends: how far the
measurement may lie from the prediction), so that each band widens steadily, the lines at +-e
(a row is covered when each of its intervals meets the band between them), the rows not
covered marked, and a summary line in the model's units. Columns with different bounds
(millimetres and radians) get an axes each. Bands stay readable at any number of rows,
where one bar per row merges into a block."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from calib_dsl.plot.values import number


def supports(data: dict[str, Any]) -> bool:
    return bool(data.get("held_out"))


def count(data: dict[str, Any]) -> int:
    return len(_groups(data))


def _groups(data: dict[str, Any]) -> dict[float, list[str]]:
    """The columns by their bound (to 3 digits: outward rounding makes cells differ)."""
    out: dict[float, list[str]] = {}
    seen: set[str] = set()
    for r in data["held_out"]:
        for name, cell in r["columns"].items():
            if name not in seen:
                seen.add(name)
                out.setdefault(float(f"{float(cell['bound']):.3g}"), []).append(name)
    return out


def errors(data: dict[str, Any]) -> tuple[dict[str, tuple[np.ndarray, np.ndarray]],
                                          np.ndarray, np.ndarray]:
    """Per column the rows' intervals of measured minus predicted (nan where the row has no
    measurement), each row's reach (the largest size of any of its ends) and whether it
    is covered."""
    rows = data["held_out"]
    names = [n for group in _groups(data).values() for n in group]
    out = {}
    for name in names:
        lo, hi = np.full(len(rows), np.nan), np.full(len(rows), np.nan)
        for i, r in enumerate(rows):
            cell = r["columns"].get(name)
            if cell is not None:
                lo[i], hi[i] = (number(v) for v in cell["error"])
        out[name] = (lo, hi)
    with np.errstate(invalid="ignore"):
        ends = np.abs(np.array([e for pair in out.values() for e in pair]))
    reach = np.nanmax(ends, axis=0) if len(ends) else np.zeros(len(rows))
    return out, reach, np.array([bool(r["covered"]) for r in rows])


def column_order(interval: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """The rows sorted by the column's guaranteed error (the larger size of its interval's
    ends; rows without one last): each band then widens steadily."""
    with np.errstate(invalid="ignore"):
        size = np.fmax(np.abs(interval[0]), np.abs(interval[1]))
    return np.argsort(np.where(np.isfinite(size), size, np.inf), kind="stable")


def summary(data: dict[str, Any], reach: np.ndarray, covered: np.ndarray,
            unit: str) -> str:
    finite = reach[np.isfinite(reach)]
    spread = (f"guaranteed |measured − predicted| per row: median {np.median(finite):.3g}, "
              f"max {np.max(finite):.3g} {unit}" if len(finite) else "no finite box")
    return (f"{len(covered)} held-out rows of {Path(data.get('at', '?')).name}: coverage "
            f"{float(np.mean(covered)):.3f} ({int(np.sum(~covered))} not covered)\n{spread}")


def draw(fig: Any, data: dict[str, Any]) -> list[Any]:
    found, reach, covered = errors(data)
    rank = np.arange(len(reach))
    groups = _groups(data)
    axes = fig.subplots(len(groups), 1, squeeze=False)[:, 0]
    for k, (ax, (bound, names)) in enumerate(zip(axes, groups.items(), strict=True)):
        for j, name in enumerate(names):
            order = column_order(found[name])
            lo, hi = (v[order] for v in found[name])
            ok = np.isfinite(lo) & np.isfinite(hi)
            ax.fill_between(rank, np.where(ok, lo, np.nan), np.where(ok, hi, np.nan),
                            color=f"C{j % 10}", alpha=0.35, linewidth=0, label=name,
                            step="mid")
            with np.errstate(invalid="ignore"):
                out = ~covered[order] & ((lo > bound) | (hi < -bound))
            if np.any(out):
                ax.plot(rank[out], 0.5 * (lo[out] + hi[out]), "x", color="red",
                        markersize=7, label="not covered" if j == 0 else None)
        for sign in (1, -1):
            ax.axhline(sign * bound, color="black", linestyle="--", linewidth=0.8,
                       label=f"±e = ±{bound:.3g}" if sign > 0 else None)
        ax.set_xlabel("held-out rows, each column's sorted by its guaranteed error")
        ax.set_ylabel("measured − predicted box")
        ax.set_label("prediction")
        ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.0, 1.0))
        if k == 0:
            ax.set_title(summary(data, reach, covered, data.get("unit") or
                                 "(the model's units)"), loc="left", fontsize="small")
    return list(axes)
