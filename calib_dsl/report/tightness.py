"""How much of an enclosure is real: per unknown, the outer width over the certified inner
width (1: the enclosure is the hull of the solution set), and a summary over the unknowns."""

from __future__ import annotations

import math
import statistics
from typing import Any

from calib_dsl.ir.program import Program
from calib_dsl.ir.status import UNKNOWNS, Status
from calib_dsl.report.extras import Extras
from calib_dsl.report.rows import parameter_rows
from calib_dsl.strategy.solution import Solution


def width_ratio(outer: tuple[float, float], inner: tuple[float, float] | None) -> float | None:
    """outer width / inner width: 1 for two equal points, inf for a point inside an interval,
    None without an inner interval."""
    if inner is None:
        return None
    wo, wi = outer[1] - outer[0], inner[1] - inner[0]
    if wi > 0:
        return wo / wi
    return 1.0 if wo == 0 else math.inf


def tightness(prog: Program, res: Solution, extra: Extras) -> dict[str, Any] | None:
    """The inner bounds' summary (None when they were not computed)."""
    inner = extra.inner
    if inner is None or res.status == Status.INFEASIBLE:
        return None
    ratios, unknowns = [], 0
    for r in parameter_rows(prog, res):
        if r["kind"] not in UNKNOWNS or r["result"][1] <= r["result"][0]:
            continue  # a known value: nothing to certify
        unknowns += 1
        q = width_ratio(r["result"], extra.inner_of(r["name"]))
        if q is not None:
            ratios.append(q)
    return {"consistent": inner.consistent, "unknowns": unknowns, "certified": len(ratios),
            "median_ratio": statistics.median(ratios) if ratios else None,
            "worst_ratio": max(ratios) if ratios else None, "points": inner.points,
            "seconds": inner.seconds}


def render_tightness(t: dict[str, Any]) -> list[str]:
    if not t["consistent"]:
        return ["inner bounds: none certified (their search proved no parameter vector to "
                "satisfy every constraint; the verdict, first in the report, says whether "
                "another proof did)"]
    lines = ["the data are consistent: a parameter vector is proven to satisfy every "
             "constraint (interval evaluation at the point)"]
    if t["certified"]:
        lines.append(f"inner bounds: certified for {t['certified']} of {t['unknowns']} "
                     f"unknowns; outer/inner widths median {t['median_ratio']:.4g}, worst "
                     f"{t['worst_ratio']:.4g} (1: the result is the best possible enclosure), "
                     f"from {t['points']} certified points")
    return lines
