"""The parameter vector an export writes (`calibc export --point`): the result box's
midpoint, the least-squares estimate (`solve --lsq`) or the certified centre (a point proven
to satisfy every constraint), each value rounded to the short decimal its enclosure's width
supports (report/decimals.py): the export's numbers carry no float noise, and what it writes
is exactly the vector whose kinematics it describes."""

from __future__ import annotations

import math
from typing import Any

from calib_dsl.frontend.diagnostics import CalError
from calib_dsl.report.decimals import number, representative

POINTS = ("midpoint", "lsq", "centre")
WHERE = {"lsq": ("least_squares", "calibc solve --lsq --json FILE writes it"),
         "centre": ("certified", "calibc solve --json FILE writes it when the inner bounds "
                                 "certified a centre")}


def export_point(data: dict[str, Any], which: str = "midpoint") -> dict[str, float]:
    """Per declared unknown, the value the export writes."""
    if which not in POINTS:
        raise CalError(f"unknown point '{which}' (one of {', '.join(POINTS)})")
    out = {}
    for name, p in data["parameters"].items():
        lo, hi = (number(v) for v in p["result"])
        if which == "midpoint":
            v = lo + (hi - lo) / 2 if math.isfinite(hi - lo) else math.nan
        else:
            key, how = WHERE[which]
            if p.get(key) is None:
                raise CalError(f"the result has no {which} value for '{name}' ({how})")
            v = float(p[key])  # (a least-squares estimate may lie outside the box)
        out[name] = representative(lo, hi, v)
    return out
